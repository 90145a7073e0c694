"""Relief is exact: every pixel shows the first point of the surface its ray meets, as an
independent slow march (fine steps and bisection against the bilinear surface of the posts,
``relief_reference``) finds it, on the built-in urban and forest surfaces and on a GeoTIFF DSM,
at 200, 300 and 3000 m. The adaptive grid it replaced had 1-2 % of this corner's pixels off
over urban, 15-22 % over the forest."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from georef_helpers import HOME, write_tif
from relief_reference import reference_hits

from air_sitl.camera import relief
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.geotiff import GeoTiffDem
from air_sitl.maps.open import open_map, open_surface
from air_sitl.maps.surface import SurfaceModel

OFF_PX = 0.5  # a pixel is off where its ground point is this far from the reference's
MAX_OFF_SHARE = 0.005  # the bound: at most 0.5 % of the pixels off
WINDOW = (slice(0, 96), slice(0, 128))  # image rows, columns: a corner, where things lean most


@pytest.fixture(scope="module")
def dsm_tif(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The urban built-in surface (seed 2) as a lidar-like GeoTIFF DSM at twice the map's
    pixel size (1.2 m), 1.5 km around home: written once for the three altitudes."""
    m = open_map("urban", HOME, seed=2)
    builtin = open_surface("builtin", m)
    assert builtin is not None
    hx, hy = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    n = 640  # level-1 pixels each side of home
    x0, y0 = round(hx / 2) - n, round(hy / 2) - n
    heights = builtin.heights(1, x0, y0, 2 * n, 2 * n)
    _, t1, t2, _, t4, t5 = m.georef.transform
    ex, ey = m.georef.px_to_crs(2 * x0 - 0.5, 2 * y0 - 0.5)  # level-1 pixel (x0, y0)'s corner
    path = tmp_path_factory.mktemp("relief_exact") / "dsm.tif"
    return write_tif(path, heights, m.georef.crs, (ex, 2 * t1, 2 * t2, ey, 2 * t4, 2 * t5))


def renderer_maps(renderer: Renderer, state: Any) -> tuple[Any, ...]:
    """The renderer's relief window, ray set-up and ground maps for one frame:
    ``(window, r, jac, geometry, cx, cy, maps)``."""
    paths = renderer._remap
    assert paths is not None
    g = renderer.geometry(state, warn=False)
    r, jac, cx, cy = paths.relief_setup(state, g.level)
    window = paths.relief_window(state, g, r, jac, cx, cy)
    cam = renderer.camera
    maps = relief.ground_maps(
        window, r, jac, g.level, cx, cy, state.alt_amsl_m, cam.width_px, cam.height_px
    )[0]
    return window, r, jac, g, cx, cy, maps


def off_share(renderer: Renderer, alt_m: float) -> tuple[float, int]:
    """(share of the window's pixels off, the frame's level) for one banked frame."""
    state = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + alt_m, alt_agl_m=alt_m,
        roll_rad=math.radians(5.0), pitch_rad=math.radians(2.0), yaw_rad=0.3,
    )  # fmt: skip
    window, r, jac, g, cx, cy, maps = renderer_maps(renderer, state)
    got = maps[WINDOW].reshape(-1, 2).astype(np.float64)
    v, u = np.mgrid[WINDOW]
    want_x, want_y = reference_hits(
        window, r, jac, g.level, cx, cy, state.alt_amsl_m, u.ravel().astype(np.float64),
        v.ravel().astype(np.float64),
    )  # fmt: skip
    off = np.hypot(got[:, 0] - want_x, got[:, 1] - want_y) > OFF_PX
    return float(off.mean()), g.level


@pytest.mark.parametrize("alt_m", [200.0, 300.0, 3000.0])
@pytest.mark.parametrize("source", ["urban", "forest", "dsm"])
def test_every_pixel_shows_the_first_surface_its_ray_meets(
    source: str, alt_m: float, request: pytest.FixtureRequest
) -> None:
    m = open_map("urban" if source == "dsm" else source, HOME, seed=2)
    surface: SurfaceModel | None
    if source == "dsm":  # the DSM opened as a DEM over the map
        surface = GeoTiffDem(request.getfixturevalue("dsm_tif"), m)
    else:
        surface = open_surface("builtin", m)
    renderer = Renderer(m, CameraModel(noise_sigma=0.0), seed=2, surface=surface)
    share, level = off_share(renderer, alt_m)
    assert level == (3 if alt_m > 1000 else 0)  # the levels the figures are about
    assert share <= MAX_OFF_SHARE, f"{100 * share:.2f} % of the pixels off by > {OFF_PX} px"


def test_the_edge_columns_of_a_100_m_forest_frame_show_the_first_surface_their_rays_meet() -> None:
    """At 100 m over the forest (the contact sheet's frame) the image edges show long
    streaks: the walls of the forest's edge, the map's colour at their foot stretched (the
    surface between a ground post and a crown post is a steep bilinear slope). They are
    the first surface the rays meet: each edge column agrees with the reference march over
    heights read 512 level pixels beyond the renderer's window on every side (a ray that
    left the renderer's window and fell back to anything else would not), and the columns
    are not copies of their neighbours."""
    m = open_map("forest", HOME, seed=0)
    renderer = Renderer(m, CameraModel(noise_sigma=0.0), surface=open_surface("builtin", m))
    state = pose_state(HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + 100.0, alt_agl_m=100.0)
    assert renderer.surface is not None
    window, r, jac, g, cx, cy, maps = renderer_maps(renderer, state)
    cam = renderer.camera
    wh, ww = window.values.shape
    big = relief.read_window(renderer.surface, g.level, window.x0 - 512, window.y0 - 512,
                             window.x0 + ww + 511, window.y0 + wh + 511)  # fmt: skip
    assert big.h_max > window.h_max  # heights the renderer's window does not hold
    edges = [0, 1, 2, 3, cam.width_px - 4, cam.width_px - 3, cam.width_px - 2, cam.width_px - 1]
    v, u = np.mgrid[0 : cam.height_px, 0 : len(edges)]
    u = np.asarray(edges)[u]
    want_x, want_y = reference_hits(
        big, r, jac, g.level, cx, cy, state.alt_amsl_m, u.ravel().astype(np.float64),
        v.ravel().astype(np.float64),
    )  # fmt: skip
    shift = np.array([window.x0 - big.x0, window.y0 - big.y0], dtype=np.float64)
    got = maps[v.ravel(), u.ravel()].astype(np.float64) + shift  # in the big window
    off = np.hypot(got[:, 0] - want_x, got[:, 1] - want_y) > OFF_PX
    assert off.mean() <= MAX_OFF_SHARE, f"{100 * off.mean():.2f} % of the edge pixels off"
    for a, b in ((0, 1), (cam.width_px - 1, cam.width_px - 2)):  # no column smeared
        assert np.abs(maps[:, a] - maps[:, b]).max(axis=1).min() > 1e-3
