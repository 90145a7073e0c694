"""Geometric exactness: marks on a UTM GeoTIFF land where the camera model projects them."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from georef_helpers import HOME, latlon_to_px, marks_image, pxs_to_latlons, utm_grid, write_tif

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import geodetic2ned, ned2geodetic
from air_sitl.maps.open import open_map

CASES = {
    200.0: {"gsd_m": 0.25, "sigma_m": 1.2, "spacing_m": 12.0, "half_m": 330.0},
    3000.0: {"gsd_m": 2.5, "sigma_m": 16.0, "spacing_m": 160.0, "half_m": 4800.0},
}


@pytest.fixture(scope="module", params=sorted(CASES))
def marks_map(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    alt = request.param
    c = CASES[alt]
    crs, transform, size = utm_grid(HOME, c["gsd_m"], c["half_m"])
    img, centres = marks_image(size, c["gsd_m"], c["spacing_m"], c["sigma_m"])
    path = write_tif(tmp_path_factory.mktemp("marks") / f"marks{int(alt)}.tif", img, crs, transform)
    return alt, path, crs, transform, centres, c


def _centroid(gray: np.ndarray, x: float, y: float, radius: float) -> tuple[float, float]:
    h, w = gray.shape
    for _ in range(4):
        x0, x1 = max(0, int(x - radius)), min(w, int(x + radius) + 2)
        y0, y1 = max(0, int(y - radius)), min(h, int(y + radius) + 2)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        inside = (xx - x) ** 2 + (yy - y) ** 2 <= radius**2
        wgt = np.clip(200.0 - gray[y0:y1, x0:x1], 0, None) * inside
        x = float((wgt * xx).sum() / wgt.sum())
        y = float((wgt * yy).sum() / wgt.sum())
    return x, y


@pytest.mark.parametrize(("roll_deg", "pitch_deg"), [(0.0, 0.0), (20.0, 10.0)])
def test_marks_land_within_half_a_pixel(marks_map, roll_deg: float, pitch_deg: float) -> None:  # type: ignore[no-untyped-def]
    alt, path, crs, transform, centres, c = marks_map
    camera = CameraModel(noise_sigma=0.0)
    m = open_map(str(path), HOME)
    renderer = Renderer(m, camera)
    lat, lon, _ = ned2geodetic(37.0, -23.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    roll, pitch, yaw = math.radians(roll_deg), math.radians(pitch_deg), 0.7
    state = pose_state(
        lat, lon, HOME.alt_amsl_m + alt, alt_agl_m=alt, roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw
    )
    gray = renderer.render(state)[:, :, 1].astype(np.float64)
    errors = []
    for mlat, mlon in pxs_to_latlons(crs, transform, centres):
        ned = geodetic2ned(mlat, mlon, HOME.alt_amsl_m, lat, lon, HOME.alt_amsl_m + alt)
        p = camera.project_ned(ned, (0.0, 0.0, 0.0), state.q_body_to_ned_wxyz)[0]
        rng_m = math.sqrt(sum(v * v for v in ned))
        sig_px = c["sigma_m"] * camera.fx_px / rng_m
        radius = 4.0 * sig_px
        if not (
            radius + 2 < p[0] < camera.width_px - radius - 3
            and radius + 2 < p[1] < camera.height_px - radius - 3
        ):
            continue
        x, y = _centroid(gray, p[0], p[1], radius)
        errors.append(math.hypot(x - p[0], y - p[1]))
    print(
        f"{alt:.0f} m roll {roll_deg} pitch {pitch_deg}: "
        f"{len(errors)} marks, max {max(errors):.3f} px"
    )
    assert len(errors) >= 12, f"only {len(errors)} marks in view"
    assert max(errors) <= 0.5, (
        f"worst mark error {max(errors):.3f} px (median {np.median(errors):.3f})"
    )


@pytest.mark.parametrize(("roll_deg", "pitch_deg"), [(0.0, 0.0), (20.0, 10.0)])
def test_image_centre_ground_point_within_one_map_pixel(
    marks_map, roll_deg: float, pitch_deg: float
) -> None:  # type: ignore[no-untyped-def]
    alt, path, crs, transform, _centres, _c = marks_map
    camera = CameraModel(noise_sigma=0.0)
    renderer = Renderer(open_map(str(path), HOME), camera)
    lat, lon, _ = ned2geodetic(-51.0, 64.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    state = pose_state(
        lat,
        lon,
        HOME.alt_amsl_m + alt,
        alt_agl_m=alt,
        roll_rad=math.radians(roll_deg),
        pitch_rad=math.radians(pitch_deg),
        yaw_rad=-2.1,
    )
    ray = camera.r_cam_to_ned(state.q_body_to_ned_wxyz) @ np.array([0.0, 0.0, 1.0])
    t = alt / ray[2]
    glat, glon, _ = ned2geodetic(t * ray[0], t * ray[1], 0.0, lat, lon, HOME.alt_amsl_m)
    truth = latlon_to_px(crs, transform, glat, glon)
    got = renderer.map_xy_px(state)
    assert got is not None
    assert math.hypot(got[0] - truth[0], got[1] - truth[1]) <= 1.0


def test_marks_file_is_real_geotiff(marks_map) -> None:  # type: ignore[no-untyped-def]
    _alt, path, _crs, _t, _c, _cc = marks_map
    assert Path(path).read_bytes()[:4] in (b"II*\x00", b"MM\x00*")
