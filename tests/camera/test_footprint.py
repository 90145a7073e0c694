"""The rendered ground footprint against 2 h tan(HFOV/2), on a GeoTIFF of known ground sample
distance: a 1 % focal-length error moves it by 1 %, far beyond this test's 0.3 %.

Truth is independent of the camera code: two dark north-south lines drawn on the map, their
ground separation measured through GDAL (pixel -> WGS84) and geodesy; the image gives the
lines' columns; the footprint is width_px * separation / (column difference)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from georef_helpers import HOME, latlon_to_px, px_to_latlon, utm_grid, write_tif

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import geodetic2ned
from air_sitl.maps.open import open_map

GSD_M = 0.25
HALF_M = 330.0


def _line_centre(profile: np.ndarray, guess: float, radius: int = 12) -> float:
    x0, x1 = int(guess) - radius, int(guess) + radius + 1
    xs = np.arange(x0, x1, dtype=np.float64)
    w = np.clip(190.0 - profile[x0:x1], 0.0, None)
    return float((w * xs).sum() / w.sum())


@pytest.mark.parametrize(("alt_m", "hfov_deg"), [(200.0, 57.0), (150.0, 40.0)])
def test_footprint_is_2h_tan_half_hfov(tmp_path, alt_m: float, hfov_deg: float) -> None:  # type: ignore[no-untyped-def]
    crs, transform, size = utm_grid(HOME, GSD_M, HALF_M)
    home_col, home_row = latlon_to_px(crs, transform, HOME.lat_deg, HOME.lon_deg)
    expected = 2.0 * alt_m * math.tan(math.radians(hfov_deg) / 2.0)
    offset_px = 0.4 * expected / GSD_M  # lines well inside the view, either side of home
    cols = (round(home_col - offset_px), round(home_col + offset_px))
    img = np.full((size, size), 200.0, dtype=np.float32)
    xx = np.arange(size, dtype=np.float32)
    for c in cols:
        img -= 150.0 * np.exp(-0.5 * ((xx - c) / 3.0) ** 2)[None, :]  # 0.75 m wide lines
    bgr = np.repeat(np.clip(img, 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    m = open_map(str(write_tif(tmp_path / "lines.tif", bgr, crs, transform)), HOME)

    # Ground separation of the lines along the row through home (GDAL + geodesy).
    ends = [px_to_latlon(crs, transform, c, home_row) for c in cols]
    east = [geodetic2ned(lat, lon, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)[1] for lat, lon in ends]
    separation_m = east[1] - east[0]

    camera = CameraModel(noise_sigma=0.0, hfov_deg=hfov_deg)
    state = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + alt_m, alt_agl_m=alt_m,
        roll_rad=0.0, pitch_rad=0.0, yaw_rad=0.0,
    )  # fmt: skip
    gray = Renderer(m, camera).render(state)[:, :, 1].astype(np.float64)
    mid = camera.height_px // 2
    profile = gray[mid - 2 : mid + 3].mean(axis=0)
    w = camera.width_px
    # The lines sit at 0.1 and 0.9 of the width (0.4 of the footprint either side of centre).
    xa = _line_centre(profile, (w - 1) / 2 - 0.4 * w)
    xb = _line_centre(profile, (w - 1) / 2 + 0.4 * w)
    footprint_m = w * separation_m / (xb - xa)
    assert footprint_m == pytest.approx(expected, rel=0.003), (footprint_m, expected)
