"""Camera effects, each off unless asked for, with physical parameters (issue 15).

- ``blur``: motion blur from the angular and linear velocity over ``exposure_time_s``: the
  frame is the mean of sub-exposures at poses spread over the exposure (as many as the
  fastest image point needs to move under half a pixel between two of them, at most 16).
- ``rolling-shutter``: sensor row ``v`` starts its exposure ``(v - (H - 1) / 2) *
  line_delay_s`` after the frame's time: each row at its own pose (ground points of the
  first, middle and last rows' poses, interpolated per row: the pose changes smoothly).
- ``vignette``: relative illumination ``cos(theta) ** vignette_power`` (theta the angle
  off the optical axis; natural vignetting is the cos^4 law, lenses correct part of it).
- ``exposure``: auto exposure: a gain bringing the frame's mean to ``exposure_target_dn``
  (within the gain limits), with frame-to-frame gain noise of ``gain_noise`` (relative std).
- ``haze``: atmospheric scattering, Koschmieder: a pixel keeps exp(-beta * range) of its
  radiance and takes the rest from the airlight; beta = 3.912 / visibility.
- ``distortion``: Brown-Conrady (OpenCV ``plumb_bob``: k1, k2, p1, p2, k3). The default is a
  small wide-angle lens (barrel) moving the corners by about 8 px; camera.yaml carries K and
  D, so ``cv2.undistort(img, K, D, None, P)`` recovers the pinhole frame.

Effects are applied before the sensor noise; a frame stays a pure function of (map, camera,
state, frame index, seed).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from air_sitl.camera.defaults import EFFECT_NAMES as NAMES
from air_sitl.errors import CameraError
from air_sitl.files import parse_yaml_mapping

DEFAULT_DISTORTION = (-0.05, 0.01, 0.0, 0.0, 0.0)


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraEffects:
    """Which effects are on, and their physical parameters."""

    enabled: tuple[str, ...] = ()
    exposure_time_s: float = 1.0 / 125.0
    line_delay_s: float = 30e-6  # 480 rows: 14.4 ms readout, a typical small CMOS sensor
    vignette_power: float = 2.5
    exposure_target_dn: float = 118.0
    exposure_gain_min: float = 0.25
    exposure_gain_max: float = 8.0
    gain_noise: float = 0.02
    visibility_m: float = 20_000.0
    airlight_bgr: tuple[float, float, float] = (205.0, 200.0, 195.0)
    distortion_coefficients: tuple[float, float, float, float, float] = DEFAULT_DISTORTION

    def __post_init__(self) -> None:
        for name in self.enabled:
            if name not in NAMES:
                msg = f"--camera-effects: {name!r} is not an effect ({', '.join(NAMES)})"
                raise CameraError(msg)
        checks = {
            "exposure_time_s": 0.0 <= self.exposure_time_s <= 0.5,
            "line_delay_s": 0.0 <= self.line_delay_s <= 1e-3,
            "vignette_power": 0.0 <= self.vignette_power <= 8.0,
            "exposure_target_dn": 1.0 <= self.exposure_target_dn <= 254.0,
            "exposure_gain_min": 0.0 < self.exposure_gain_min <= self.exposure_gain_max,
            "gain_noise": 0.0 <= self.gain_noise <= 0.5,
            "visibility_m": self.visibility_m > 0.0,
            "distortion_coefficients": len(self.distortion_coefficients) == 5
            and all(math.isfinite(c) and abs(c) < 10 for c in self.distortion_coefficients),
        }
        for name, ok in checks.items():
            if not ok:
                msg = f"camera profile: {name} = {getattr(self, name)!r} is out of range"
                raise CameraError(msg)

    def on(self, name: str) -> bool:
        """Whether effect ``name`` is enabled."""
        return name in self.enabled

    @property
    def distortion(self) -> tuple[float, float, float, float, float]:
        """The plumb_bob coefficients in effect (zeros without the distortion effect)."""
        return self.distortion_coefficients if self.on("distortion") else (0.0,) * 5

    def settings(self) -> dict[str, Any]:
        """JSON values: ``effects_from_settings(settings())`` rebuilds it."""
        out: dict[str, Any] = {}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if isinstance(value, tuple) else value
        return out


def effects_from_settings(settings: Mapping[str, Any]) -> CameraEffects:
    """Parse a mapping (a camera profile YAML, remote settings) into CameraEffects."""
    known = {f.name for f in fields(CameraEffects)}
    unknown = sorted(set(settings) - known - {"effects"})
    if unknown:
        names = ", ".join(sorted(known))
        msg = f"camera profile: unknown key(s) {', '.join(unknown)} (known: {names})"
        raise CameraError(msg)
    values: dict[str, Any] = {}
    for key, value in settings.items():
        if key in ("enabled", "effects"):
            values["enabled"] = _names(value)
        elif key in ("airlight_bgr", "distortion_coefficients"):
            values[key] = tuple(float(v) for v in value)
        else:
            values[key] = float(value)
    return CameraEffects(**values)


def _names(value: str | Sequence[str]) -> tuple[str, ...]:
    items = value.split(",") if isinstance(value, str) else list(value)
    return tuple(dict.fromkeys(str(v).strip() for v in items if str(v).strip()))


def effects_from_options(profile: str | None, names: str | None) -> CameraEffects | None:
    """``--camera-profile FILE.yaml`` and/or ``--camera-effects a,b``: None when neither."""
    if profile is None and not names:
        return None
    effects = CameraEffects()
    if profile is not None:
        path = Path(profile)
        try:
            text = path.read_text()
        except OSError as err:
            msg = f"--camera-profile {path}: cannot read it ({err})"
            raise CameraError(msg) from None
        data = parse_yaml_mapping(text, f"--camera-profile {path}", CameraError)
        try:
            effects = effects_from_settings(data)
        except (TypeError, ValueError) as err:
            msg = f"--camera-profile {path}: {err}"
            raise CameraError(msg) from None
    if names:
        effects = replace(effects, enabled=tuple(dict.fromkeys(effects.enabled + _names(names))))
    return effects


def undistorted_grid(
    width: int, height: int, k: npt.NDArray[np.float64], coeffs: Sequence[float], margin: int = 0
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
    """Pinhole pixel (u, v) seen at each distorted sensor pixel (inverse of plumb_bob), on
    the sensor's grid and ``margin`` pixels around it (rows and columns -margin ..)."""
    v, u = np.mgrid[-margin : height + margin, -margin : width + margin].astype(np.float64)
    return undistort_points(u, v, k, coeffs)


def undistort_points(
    u: npt.NDArray[np.float64], v: npt.NDArray[np.float64], k: npt.NDArray[np.float64],
    coeffs: Sequence[float],
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:  # fmt: skip
    """Pinhole points seen at distorted sensor points (u, v) (inverse of plumb_bob).

    Fixed-point iteration on normalised coordinates to 1e-10, as OpenCV's undistortPoints
    does with more iterations (its default five leave 0.1 px at strong distortion).
    """
    fx, fy, cx, cy = k[0, 0], k[1, 1], k[0, 2], k[1, 2]
    k1, k2, p1, p2, k3 = (float(c) for c in coeffs)
    xd, yd = (u - cx) / fx, (v - cy) / fy
    x, y = xd.copy(), yd.copy()
    for _ in range(50):
        r2 = x * x + y * y
        radial = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
        dx = 2 * p1 * x * y + p2 * (r2 + 2 * x * x)
        dy = p1 * (r2 + 2 * y * y) + 2 * p2 * x * y
        nx, ny = (xd - dx) / radial, (yd - dy) / radial
        step = float(np.max(np.abs(nx - x) + np.abs(ny - y)))
        x, y = nx, ny
        if step < 1e-10:
            break
    return x * fx + cx, y * fy + cy


def vignette_gain(
    width: int, height: int, k: npt.NDArray[np.float64], pu: npt.NDArray[np.float64],
    pv: npt.NDArray[np.float64], power: float,
) -> npt.NDArray[np.float32]:  # fmt: skip
    """cos(theta) ** power per pixel, theta the ray's angle off the optical axis."""
    x = (pu - k[0, 2]) / k[0, 0]
    y = (pv - k[1, 2]) / k[1, 1]
    cos = 1.0 / np.sqrt(1.0 + x * x + y * y)
    gain: npt.NDArray[np.float32] = (cos**power).astype(np.float32)
    return gain
