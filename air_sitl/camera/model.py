"""The pinhole camera: intrinsics from width, height and horizontal FOV; rigid mounting.

Default mounting (SPEC section 2): optical axis along body +z (down), image x (right) along the
right wing (body +y), image y (down the image) toward the tail (body -x): the nose is at the
top of the image. ``mount_rpy_deg`` rotates the camera away from that default as if the
airframe were rolled, pitched and yawed (ZYX, degrees) about its own axes:
``R_cam_to_body = R(mount_rpy) @ R_default``. Pixel centres are at integer coordinates and the
principal point is the image centre ((W - 1) / 2, (H - 1) / 2). No lens distortion unless
the ``distortion`` effect is on (:mod:`air_sitl.camera.effects`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from air_sitl.camera.defaults import DEFAULT_JPEG_QUALITY, DEFAULT_NOISE_SIGMA
from air_sitl.camera.effects import CameraEffects
from air_sitl.errors import CameraError
from air_sitl.frames import euler2quat, quat2matrix
from air_sitl.state import Quat

Mat3 = npt.NDArray[np.float64]

_R_DEFAULT_CAM_TO_BODY: Mat3 = np.array(
    [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=np.float64
)  # columns: camera x = body +y, camera y = body -x, camera z = body +z


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraModel:
    """Image size, field of view, mounting, and the sensor's noise and JPEG settings."""

    width_px: int = 640
    height_px: int = 480
    hfov_deg: float = 57.0
    mount_rpy_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    noise_sigma: float = DEFAULT_NOISE_SIGMA  # grey levels (0..255), 0 = no noise
    jpeg_quality: int = DEFAULT_JPEG_QUALITY
    effects: CameraEffects | None = None  # None: the perfect pinhole (frames as before)

    def __post_init__(self) -> None:
        if not (16 <= self.width_px <= 8192 and 16 <= self.height_px <= 8192):
            msg = f"camera size {self.width_px}x{self.height_px}: expected 16..8192 pixels"
            raise CameraError(msg)
        if not (1.0 <= self.hfov_deg <= 170.0):
            msg = f"--camera-hfov-deg {self.hfov_deg}: expected 1..170 degrees"
            raise CameraError(msg)
        if not (math.isfinite(self.noise_sigma) and 0.0 <= self.noise_sigma <= 100.0):
            msg = f"--noise-sigma {self.noise_sigma}: expected 0..100 grey levels"
            raise CameraError(msg)
        if not (1 <= self.jpeg_quality <= 100):
            msg = f"--jpeg-quality {self.jpeg_quality}: expected 1..100"
            raise CameraError(msg)
        if len(self.mount_rpy_deg) != 3 or not all(math.isfinite(a) for a in self.mount_rpy_deg):
            msg = f"--camera-mount-rpy-deg {self.mount_rpy_deg}: expected 3 finite angles"
            raise CameraError(msg)

    def settings(self) -> dict[str, Any]:
        """The configuration as JSON values (``camera_from_settings`` rebuilds it)."""
        out: dict[str, Any] = {
            "width_px": self.width_px,
            "height_px": self.height_px,
            "hfov_deg": self.hfov_deg,
            "mount_rpy_deg": list(self.mount_rpy_deg),
            "noise_sigma": self.noise_sigma,
            "jpeg_quality": self.jpeg_quality,
        }
        if self.effects is not None:
            out["effects"] = self.effects.settings()
        return out

    @property
    def has_effects(self) -> bool:
        """Whether any camera effect is on."""
        return self.effects is not None and bool(self.effects.enabled)

    @property
    def fx_px(self) -> float:
        """Focal length in pixels: (W/2) / tan(HFOV/2), about 589.3 for 640 px and 57 deg."""
        return (self.width_px / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)

    @property
    def fy_px(self) -> float:
        """Square pixels: fy = fx."""
        return self.fx_px

    @property
    def cx_px(self) -> float:
        """Principal point x: the image centre."""
        return (self.width_px - 1) / 2.0

    @property
    def cy_px(self) -> float:
        """Principal point y: the image centre."""
        return (self.height_px - 1) / 2.0

    def intrinsics(self) -> Mat3:
        """The 3x3 intrinsics matrix K."""
        return np.array(
            [[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]]
        )

    def r_cam_to_body(self) -> Mat3:
        """Rotation taking camera-frame vectors to body FRD."""
        roll, pitch, yaw = (math.radians(a) for a in self.mount_rpy_deg)
        mount = np.array(quat2matrix(euler2quat(roll, pitch, yaw)), dtype=np.float64)
        return mount @ _R_DEFAULT_CAM_TO_BODY

    def r_cam_to_ned(self, q_body_to_ned_wxyz: Quat) -> Mat3:
        """Rotation taking camera-frame vectors to NED for an attitude."""
        r_b2n = np.array(quat2matrix(q_body_to_ned_wxyz), dtype=np.float64)
        return r_b2n @ self.r_cam_to_body()

    def project_ned(
        self,
        points_ned_m: npt.ArrayLike,
        camera_ned_m: npt.ArrayLike,
        q_body_to_ned_wxyz: Quat,
    ) -> npt.NDArray[np.float64]:
        """Pixel (x, y) of NED points seen from a camera position; NaN behind the camera."""
        p = np.atleast_2d(np.asarray(points_ned_m, dtype=np.float64)) - np.asarray(
            camera_ned_m, dtype=np.float64
        )
        v = p @ self.r_cam_to_ned(q_body_to_ned_wxyz)  # rows: (R^T p)^T
        out = np.full((p.shape[0], 2), np.nan)
        front = v[:, 2] > 1e-9
        out[front, 0] = self.fx_px * v[front, 0] / v[front, 2] + self.cx_px
        out[front, 1] = self.fy_px * v[front, 1] / v[front, 2] + self.cy_px
        return out
