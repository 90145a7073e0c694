"""Camera effects, each measured: distortion undone by cv2.undistort with camera.yaml's K and D,
rolling-shutter shear, motion-blur length, vignetting, auto exposure, haze; options, YAML."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
import yaml
from georef_helpers import HOME, marks_image, utm_grid

from air_sitl.camera.effects import CameraEffects, effects_from_options
from air_sitl.camera.info import camera_yaml_for
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.errors import CameraError
from air_sitl.maps.array import ArrayMap
from air_sitl.state import VehicleState

GSD = 0.5


@pytest.fixture(scope="module")
def marks() -> ArrayMap:
    crs, transform, size = utm_grid(HOME, GSD, 500.0)
    image, _ = marks_image(size, GSD, 9.0, 0.9)
    return ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)


def grey_map(value: int) -> ArrayMap:
    crs, transform, size = utm_grid(HOME, 2.0, 3000.0)
    image = np.full((size, size, 3), value, dtype=np.uint8)
    return ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)


def still(alt_agl_m: float = 200.0, roll_rate_deg_s: float = 0.0) -> VehicleState:
    s = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + alt_agl_m, alt_agl_m=alt_agl_m, yaw_rad=0.2
    )
    return replace(s, rate_frd_rad_s=(math.radians(roll_rate_deg_s), 0.0, 0.0))


def camera(*names: str, **params: object) -> CameraModel:
    return CameraModel(noise_sigma=0.0, effects=CameraEffects(enabled=names, **params))  # type: ignore[arg-type]


def dots(img: npt.NDArray[np.uint8], border: int = 8) -> npt.NDArray[np.float64]:
    """Dark dots: (x, y, var_x, var_y) from weighted moments in a window around each."""
    dark = np.clip(200.0 - cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64), 0, None)
    n, _labels, _stats, cents = cv2.connectedComponentsWithStats((dark > 60).astype(np.uint8))
    out = []
    h, w = dark.shape
    for k in range(1, n):
        cx, cy = cents[k]
        if not (border + 10 < cx < w - border - 10 and border + 10 < cy < h - border - 10):
            continue
        x0, y0 = round(cx) - 10, round(cy) - 10
        win = dark[y0 : y0 + 21, x0 : x0 + 21]
        yy, xx = np.mgrid[y0 : y0 + 21, x0 : x0 + 21]
        s = win.sum()
        mx, my = (win * xx).sum() / s, (win * yy).sum() / s
        vx, vy = (win * (xx - mx) ** 2).sum() / s, (win * (yy - my) ** 2).sum() / s
        out.append((mx, my, vx, vy))
    return np.array(out)


def match(a: npt.NDArray[np.float64], b: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """For each dot of a, the offset (dx, dy) to the nearest dot of b."""
    d = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])
    j = d.argmin(axis=1)
    return b[j, :2] - a[:, :2]


def test_undistort_with_camera_yaml_recovers_the_pinhole_frame(marks: ArrayMap) -> None:
    cam = camera("distortion")
    info = yaml.safe_load(camera_yaml_for(cam))
    k = np.array(info["camera_matrix"]["data"]).reshape(3, 3)
    d = np.array(info["distortion_coefficients"]["data"])
    p = np.array(info["projection_matrix"]["data"]).reshape(3, 4)[:, :3]
    assert info["distortion_model"] == "plumb_bob" and d[0] < 0
    state = still()
    pinhole = Renderer(marks, CameraModel(noise_sigma=0.0)).render(state)
    distorted = Renderer(marks, cam).render(state)
    # A typical small wide-angle lens: the corners move by several pixels.
    corner = np.array([[[0.0, 0.0]]])
    moved = cv2.undistortPoints(corner, k, d, P=k).reshape(2)
    assert 5.0 < float(np.hypot(*(moved - corner.reshape(2)))) < 20.0
    undone = np.asarray(cv2.undistort(distorted, k, d, None, p), dtype=np.uint8)
    a, b = dots(pinhole), dots(undone, border=20)
    off = match(b, a)
    assert len(b) > 200
    assert float(np.abs(off).max()) < 0.5, float(np.abs(off).max())
    # Without undistorting, points near the edges sit several pixels away: barrel.
    raw = match(dots(distorted, border=20), a)
    assert float(np.hypot(raw[:, 0], raw[:, 1]).max()) > 3.0


def test_rolling_shutter_shears_a_rolling_frame_as_computed(marks: ArrayMap) -> None:
    rate = 60.0
    delay = 30e-6
    state = still(roll_rate_deg_s=rate)
    glob = dots(Renderer(marks, CameraModel(noise_sigma=0.0)).render(state))
    rs = dots(Renderer(marks, camera("rolling-shutter", line_delay_s=delay)).render(state))
    off = match(glob, rs)
    good = np.hypot(off[:, 0], off[:, 1]) < 10.0  # dots near the edges may lose their pair
    glob, off = glob[good], off[good]
    assert len(glob) > 200
    cam = CameraModel()
    # Rolling moves a point at image column x sideways at f * p * (1 + ((x - cx) / f)^2) px/s
    # (nadir view, rotation about the image's y axis); row v is (v - cy) * delay late.
    spread = 1.0 + ((glob[:, 0] - cam.cx_px) / cam.fx_px) ** 2
    slope, _ = np.polyfit(glob[:, 1] - cam.cy_px, off[:, 0] / spread, 1)
    expected = cam.fx_px * math.radians(rate) * delay
    assert abs(slope) == pytest.approx(expected, rel=0.03), (slope, expected)
    assert float(np.median(np.abs(off[:, 1]))) < 0.3  # a roll moves the image sideways


def test_motion_blur_grows_with_the_roll_rate_as_computed(marks: ArrayMap) -> None:
    exposure = 1.0 / 125.0
    cam = camera("blur", exposure_time_s=exposure)
    sharp = Renderer(marks, cam).render(still())
    base = dots(sharp)
    sharpness = []
    for rate in (0.0, 20.0, 60.0):
        img = Renderer(marks, cam).render(still(roll_rate_deg_s=rate))
        sharpness.append(
            float(cv2.Laplacian(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), cv2.CV_64F).var())
        )
        if rate == 60.0:
            blurred = dots(img)
            # A box of length L adds L^2 / 12 to the variance along the motion (image x).
            length = CameraModel().fx_px * math.radians(rate) * exposure
            grow = float(
                np.median(blurred[:, 2] - blurred[:, 3]) - np.median(base[:, 2] - base[:, 3])
            )
            assert grow == pytest.approx(length**2 / 12.0, rel=0.3), (grow, length)
    assert sharpness[0] > sharpness[1] > sharpness[2]
    assert sharpness[2] < 0.7 * sharpness[0]


def test_vignetting_follows_the_cos_power_law() -> None:
    power = 2.5
    img = Renderer(grey_map(200), camera("vignette", vignette_power=power)).render(still())
    cam = CameraModel()
    theta = math.atan(math.hypot(cam.cx_px, cam.cy_px) / cam.fx_px)
    centre = float(img[238:242, 318:322].mean())
    corner = float(img[0, 0].mean())
    assert centre == pytest.approx(200.0, abs=1.0)
    assert corner / centre == pytest.approx(math.cos(theta) ** power, abs=0.01)


def test_auto_exposure_reaches_its_target_with_gain_noise() -> None:
    dark = grey_map(40)
    steady = Renderer(dark, camera("exposure", gain_noise=0.0, exposure_target_dn=118.0))
    assert float(steady.render(still(), noise_index=0).mean()) == pytest.approx(118.0, abs=1.5)
    noisy = Renderer(dark, camera("exposure", gain_noise=0.03), seed=4)
    means = np.array([noisy.render(still(), noise_index=i).mean() for i in range(40)])
    assert float(means.std() / means.mean()) == pytest.approx(0.03, rel=0.35)
    again = Renderer(dark, camera("exposure", gain_noise=0.03), seed=4)
    assert float(again.render(still(), noise_index=5).mean()) == pytest.approx(float(means[5]))


def test_haze_grows_with_range() -> None:
    vis = 5000.0
    r = Renderer(grey_map(100), camera("haze", visibility_m=vis, airlight_bgr=(205, 205, 205)))
    img = r.render(still(alt_agl_m=1000.0)).astype(np.float64)
    keep = math.exp(-3.912 / vis * 1000.0)
    assert float(img[239:241, 319:321].mean()) == pytest.approx(
        100 * keep + 205 * (1 - keep), abs=1.0
    )
    assert float(img[0, 0].mean()) > float(img[239:241, 319:321].mean()) + 3.0


def test_no_effects_keep_camera_yaml_and_options(tmp_path: Path) -> None:
    plain = yaml.safe_load(camera_yaml_for(CameraModel()))
    assert plain["distortion_coefficients"]["data"] == [0.0] * 5
    assert "effects" not in plain and "exposure_time_s" not in plain
    assert effects_from_options(None, None) is None
    profile = tmp_path / "cam.yaml"
    profile.write_text("enabled: [blur, haze]\nexposure_time_s: 0.004\nvisibility_m: 8000\n")
    fx = effects_from_options(str(profile), "vignette")
    assert fx is not None and fx.enabled == ("blur", "haze", "vignette")
    info = yaml.safe_load(camera_yaml_for(CameraModel(effects=fx)))
    assert info["exposure_time_s"] == 0.004 and info["effects"]["visibility_m"] == 8000.0
    with pytest.raises(CameraError, match="not an effect"):
        effects_from_options(None, "blur,sparkle")
    profile.write_text("exposure_time: 1\n")
    with pytest.raises(CameraError, match="unknown key"):
        effects_from_options(str(profile), None)
