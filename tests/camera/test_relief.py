"""Relief: points on a plateau image where the pinhole at the reduced height says, a tall
block hides what is behind it, DEM files of any CRS with nodata holes, the built-in surface."""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt
import pytest
import rasterio
import yaml
from georef_helpers import HOME, marks_image, utm_grid, write_tif
from rasterio.transform import Affine
from rasterio.warp import Resampling, calculate_default_transform, reproject

from air_sitl.camera import relief as relief_mod
from air_sitl.camera import relief_march
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state, render_camera_frame
from air_sitl.maps.array import ArrayMap
from air_sitl.maps.geotiff import GeoTiffDem
from air_sitl.maps.open import open_map, open_surface
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.surface import ProceduralSurface
from air_sitl.state import CameraTick, VehicleState, mission_sample

GSD = 1.0
HALF = 1000.0
PLATEAU_M = 60.0  # above home's ground, 200 m square around home


def plateau_dem(
    path: Path, crs: str, transform: tuple[float, float, float, float, float, float]
) -> Path:
    """A DEM on the marks map's grid: a plateau PLATEAU_M high, 200 m each way from home."""
    size, half_px = round(2 * HALF / GSD), 200
    h = np.full((size, size), HOME.alt_amsl_m, dtype=np.float32)
    c = size // 2
    h[c - half_px : c + half_px, c - half_px : c + half_px] = HOME.alt_amsl_m + PLATEAU_M
    return write_tif(path, h, crs, transform)


@pytest.fixture(scope="module")
def marks_map() -> tuple[ArrayMap, str, tuple[float, float, float, float, float, float]]:
    crs, transform, size = utm_grid(HOME, GSD, HALF)
    image, _ = marks_image(size, GSD, 12.0, 1.2)
    m = ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    return m, crs, transform


def _pose(alt_amsl_m: float, roll_deg: float = 0.0) -> VehicleState:
    return pose_state(
        HOME.lat_deg, HOME.lon_deg, alt_amsl_m, alt_agl_m=alt_amsl_m - HOME.alt_amsl_m,
        roll_rad=math.radians(roll_deg), pitch_rad=0.02, yaw_rad=0.3,
    )  # fmt: skip


def _dots(img: npt.NDArray[np.uint8]) -> npt.NDArray[np.float64]:
    """Sub-pixel centroids of the dark dots of a frame."""
    gray = 255.0 - cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64)
    mask = (gray > 110).astype(np.uint8)
    n, labels, stats, _ = cv2.connectedComponentsWithStats(mask)
    out = []
    for k in range(1, n):
        x, y, w, h, area = stats[k]
        if area < 6 or x == 0 or y == 0 or x + w >= img.shape[1] or y + h >= img.shape[0]:
            continue
        ys, xs = np.nonzero(labels == k)
        wgt = gray[ys, xs] - 110
        out.append((float((xs * wgt).sum() / wgt.sum()), float((ys * wgt).sum() / wgt.sum())))
    return np.array(out)


def test_points_on_a_plateau_image_as_the_pinhole_at_the_reduced_height(
    marks_map: tuple[ArrayMap, str, tuple[float, float, float, float, float, float]],
    tmp_path: Path,
) -> None:
    m, crs, transform = marks_map
    size = round(2 * HALF / GSD)
    dem = plateau_dem(tmp_path / "plateau.tif", crs, transform)
    camera = CameraModel(noise_sigma=0.0)
    relief = Renderer(m, camera, surface=GeoTiffDem(dem, m))
    state = _pose(HOME.alt_amsl_m + 250.0, roll_deg=4.0)
    # The pinhole model at the reduced height: the same map as a plane at the plateau's top.
    pixels = np.ascontiguousarray(m.read_level(0, 0, 0, size, size)[:, :, :3], dtype=np.uint8)
    top = ArrayMap(
        pixels, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m + PLATEAU_M
    )
    flat = Renderer(top, camera)
    got, want = _dots(relief.render(state)), _dots(flat.render(state))
    assert len(want) > 100
    dist = np.hypot(got[:, None, 0] - want[None, :, 0], got[:, None, 1] - want[None, :, 1])
    nearest = dist.min(axis=0)
    assert float(np.max(nearest)) < 0.5, float(np.max(nearest))
    # The centre point (MapX/MapY) is where the centre ray meets the plateau.
    a, b = relief.map_xy_px(state), flat.map_xy_px(state)
    assert a is not None and b is not None
    assert math.hypot(a[0] - b[0], a[1] - b[1]) < 0.05


def test_a_tall_block_leans_outward_and_hides_the_ground_behind_it(tmp_path: Path) -> None:
    crs, transform, size = utm_grid(HOME, GSD, 500.0)
    image = np.full((size, size, 3), 128, dtype=np.uint8)
    heights = np.full((size, size), HOME.alt_amsl_m, dtype=np.float32)
    c = size // 2
    # A 100 m tower 40-60 m east of home (blue roof); red ground 5-25 m east behind it.
    image[c - 10 : c + 10, c + 40 : c + 60] = (255, 0, 0)
    heights[c - 10 : c + 10, c + 40 : c + 60] += 100.0
    image[c - 10 : c + 10, c + 65 : c + 85] = (0, 0, 255)
    m = ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    dem = write_tif(tmp_path / "tower.tif", heights, crs, transform)
    camera = CameraModel(noise_sigma=0.0)
    state = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + 300.0, alt_agl_m=300.0, yaw_rad=0.0
    )
    flat = Renderer(m, camera).render(state)
    relief = Renderer(m, camera, surface=GeoTiffDem(dem, m)).render(state)

    def count(img: npt.NDArray[np.uint8], bgr: tuple[int, int, int]) -> int:
        return int((np.abs(img.astype(int) - bgr).sum(axis=2) < 60).sum())

    red_flat, red_relief = count(flat, (0, 0, 255)), count(relief, (0, 0, 255))
    assert red_flat > 1000
    # Hidden length behind the far wall: 100 m * 60 m / (300 m - 100 m) = 30 m > 25 m.
    assert red_relief < 0.02 * red_flat, (red_flat, red_relief)

    # The roof's far edge (blue) images 300 / 200 = 1.5 times as far from the nadir as the
    # ground's; the walls between show the colour at the tower's foot (blue too).
    def far_x(img: npt.NDArray[np.uint8]) -> float:
        _ys, xs = np.nonzero(np.abs(img.astype(int) - (255, 0, 0)).sum(axis=2) < 200)
        return float(xs.max())

    cx = camera.cx_px
    ratio = (far_x(relief) - cx) / (far_x(flat) - cx)
    assert ratio == pytest.approx(1.5, rel=0.01)


def test_a_dem_in_another_crs_with_nodata_holes_is_filled_with_a_warning(
    marks_map: tuple[ArrayMap, str, tuple[float, float, float, float, float, float]],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    m, crs, transform = marks_map
    size = round(2 * HALF / GSD)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    smooth = (HOME.alt_amsl_m + 30.0 * np.sin(xx / 300.0) * np.cos(yy / 250.0)).astype(np.float32)
    utm = write_tif(tmp_path / "utm.tif", smooth, crs, transform)
    # The same relief in geographic coordinates, with a nodata hole.
    src_affine = Affine(transform[1], 0.0, transform[0], 0.0, transform[5], transform[3])
    bounds = rasterio.transform.array_bounds(size, size, src_affine)
    dst_t, w, h = calculate_default_transform(crs, "EPSG:4326", size, size, *bounds)
    geo = np.full((h, w), -9999.0, dtype=np.float32)
    reproject(
        smooth, geo, src_transform=src_affine, src_crs=crs, dst_transform=dst_t,
        dst_crs="EPSG:4326",
        resampling=Resampling.bilinear, dst_nodata=-9999.0,
    )  # fmt: skip
    geo[h // 2 - 3 : h // 2 + 3, w // 2 - 3 : w // 2 + 3] = -9999.0
    with rasterio.open(
        tmp_path / "geo.tif", "w", driver="GTiff", width=w, height=h, count=1, dtype="float32",
        crs="EPSG:4326", transform=dst_t, nodata=-9999.0,
    ) as dst:  # fmt: skip
        dst.write(geo, 1)
    a = GeoTiffDem(utm, m)
    b = GeoTiffDem(tmp_path / "geo.tif", m)
    hx, hy = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    x0, y0 = round(hx) - 300, round(hy) - 300
    ha, hb = a.heights(0, x0, y0, 600, 600), b.heights(0, x0, y0, 600, 600)
    assert float(np.abs(ha - hb).max()) < 1.0  # the hole, filled from its rim
    assert float(np.median(np.abs(ha - hb))) < 0.05
    assert "nodata" in capsys.readouterr().err


def test_builtin_surfaces_have_roofs_crowns_and_terrain_through_home() -> None:
    for kind in ("urban", "forest"):
        m = open_map(kind, HOME)
        s = open_surface("builtin", m)
        assert isinstance(s, ProceduralSurface)
        assert s.terrain_at(HOME.lat_deg, HOME.lon_deg) == pytest.approx(HOME.alt_amsl_m, abs=1e-3)
        hx, hy = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
        h = s.heights(0, round(hx) - 256, round(hy) - 256, 512, 512)
        assert float(h.max() - h.min()) > 8.0  # roofs / canopy over the terrain
    # Roofs where houses are drawn: roof pixels differ in colour from the lawn around them.
    m = open_map("urban", HOME)
    assert isinstance(m, ProceduralMap)
    s = ProceduralSurface(m)
    hx, hy = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    x0, y0 = round(hx) - 256, round(hy) - 256
    tall = s.heights(0, x0, y0, 512, 512) > s.terrain_at(HOME.lat_deg, HOME.lon_deg) + 4.0
    img = m.read_level(0, x0, y0, 512, 512)[:, :, :3].astype(int)
    green = (img[:, :, 1] > img[:, :, 2] + 15) & (img[:, :, 1] > img[:, :, 0] + 15)
    # Lawns are green; trees too, so among tall pixels green means crowns, the rest roofs.
    assert tall.mean() > 0.03
    assert (~green[tall]).mean() > 0.3


def test_render_command_with_builtin_relief_and_an_absolute_altitude(tmp_path: Path) -> None:
    from air_sitl.cli import main

    out = tmp_path / "relief.png"
    base = ["render", "--map", "urban", "--lat", str(HOME.lat_deg), "--lon", str(HOME.lon_deg)]
    base += ["--ground-alt-m", str(HOME.alt_amsl_m), "--dem", "builtin", "--out", str(out)]
    assert main([*base, "--alt-amsl", str(HOME.alt_amsl_m + 200.0)]) == 0
    img = cv2.imread(str(out))
    assert img is not None
    assert img.shape == (480, 640, 3) and img.std() > 10
    # One of --alt-agl / --alt-amsl, not both; not under the surface.
    assert main([*base, "--alt-amsl", "400", "--alt-agl", "200"]) == 2  # usage error
    assert main([*base, "--alt-amsl", str(HOME.alt_amsl_m - 50.0)]) == 2


def test_a_map_much_coarser_than_the_camera_is_named_once(
    capsys: pytest.CaptureFixture[str],
) -> None:
    crs, transform, size = utm_grid(HOME, 2.0, 1000.0)
    image = np.full((size, size, 3), 90, dtype=np.uint8)
    m = ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    r = Renderer(m, CameraModel(noise_sigma=0.0))
    for _ in range(3):
        r.render(_pose(HOME.alt_amsl_m + 200.0))
    err = capsys.readouterr().err
    assert err.count("coarser than the camera") == 1
    assert "2.00 m pixels are 5.8x coarser than the camera's 0.34 m at 200 m" in err


@pytest.mark.parametrize(("capture_index", "warnings"), [(None, 0), (0, 1)])
def test_only_frames_of_the_capture_window_name_a_coarse_map(
    capsys: pytest.CaptureFixture[str], capture_index: int | None, warnings: int
) -> None:
    # A camera on for an aid renders take-off and landing too: there every map is coarse.
    crs, transform, size = utm_grid(HOME, 2.0, 1000.0)
    image = np.full((size, size, 3), 90, dtype=np.uint8)
    m = ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    r = Renderer(m, CameraModel(noise_sigma=0.0))
    tick = CameraTick(index=0, capture_index=capture_index)
    sample = dataclasses.replace(mission_sample(_pose(HOME.alt_amsl_m + 20.0)), camera=tick)
    render_camera_frame(r, sample, 0)
    assert capsys.readouterr().err.count("coarser than the camera") == warnings


def test_lens_distortion_over_relief_is_undone_by_camera_yaml(
    marks_map: tuple[ArrayMap, str, tuple[float, float, float, float, float, float]],
    tmp_path: Path,
) -> None:
    from air_sitl.camera.effects import CameraEffects
    from air_sitl.camera.info import camera_yaml_for

    m, crs, transform = marks_map
    surface = GeoTiffDem(plateau_dem(tmp_path / "plateau.tif", crs, transform), m)
    state = _pose(HOME.alt_amsl_m + 250.0, roll_deg=4.0)
    lens = CameraModel(noise_sigma=0.0, effects=CameraEffects(enabled=("distortion",)))
    info = yaml.safe_load(camera_yaml_for(lens))
    k = np.array(info["camera_matrix"]["data"]).reshape(3, 3)
    d = np.array(info["distortion_coefficients"]["data"])
    pinhole = Renderer(m, CameraModel(noise_sigma=0.0), surface=surface).render(state)
    distorted = Renderer(m, lens, surface=surface).render(state)
    undone = np.asarray(cv2.undistort(distorted, k, d, None, k), dtype=np.uint8)
    got, want = _dots(undone[20:-20, 20:-20]), _dots(pinhole[20:-20, 20:-20])
    dist = np.hypot(got[:, None, 0] - want[None, :, 0], got[:, None, 1] - want[None, :, 1])
    assert len(got) > 100
    assert float(dist.min(axis=1).max()) < 0.5


def _bilinear(
    v: npt.NDArray[np.float32], x: npt.NDArray[np.float64], y: npt.NDArray[np.float64]
) -> npt.NDArray[np.float64]:
    h, w = v.shape
    x, y = np.clip(x, 0, w - 1), np.clip(y, 0, h - 1)
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = x - x0, y - y0
    top = v[y0, x0] * (1 - fx) + v[y0, x1] * fx
    return top * (1 - fy) + (v[y1, x0] * (1 - fx) + v[y1, x1] * fx) * fy  # type: ignore[no-any-return]


def test_the_compiled_march_finds_the_first_surface_dense_sampling_finds() -> None:
    """Rays over blocks on rough ground against sampling every 2 mm of altitude: the exact
    walk (``first_hit``) agrees but for grazes sampling misses; the fine march that rays
    leaving the window take (max-height tiles skipped, one-pixel steps, refinement) agrees
    except where a ray only grazes a block's corner between two steps, as often as without
    the tiles (give or take a graze: the steps after a skip fall elsewhere)."""
    rng = np.random.default_rng(1)
    v = np.full((96, 96), HOME.alt_amsl_m, dtype=np.float32)
    for _ in range(40):  # blocks 3-12 px wide, 2-40 m tall
        x, y = rng.integers(0, 90, 2)
        a, b = rng.integers(3, 13, 2)
        v[y : y + b, x : x + a] = HOME.alt_amsl_m + rng.uniform(2.0, 40.0)
    v += rng.uniform(0.0, 0.5, v.shape).astype(np.float32)
    tops, no_tiles = relief_march.tile_max(v), np.full((12, 12), np.inf, dtype=np.float32)
    assert tops.shape == no_tiles.shape
    z_top, z_bot = float(v.max()), float(v.min())
    zz = np.arange(z_top, z_bot, -0.002)
    agree = {"tiles": 0, "no tiles": 0, "exact": 0}
    cells, inside = relief_march.cell_max(v), 0
    n = 600
    for slope in rng.uniform(-2.0, 2.0, (n, 2)):
        ax, ay = float(slope[0]), float(slope[1])
        px0, py0 = rng.uniform(10.0, 86.0, 2) + 150.0 * slope  # over the window at 150 m AMSL
        f = zz - _bilinear(v, px0 - zz * ax, py0 - zz * ay)
        under = np.flatnonzero(f <= 0)
        want = zz[under[0]] if under.size else z_bot
        for name, t in (("tiles", tops), ("no tiles", no_tiles)):
            z, found = relief_march.march_ray(v, t, px0, py0, ax, ay, z_top, z_bot)
            agree[name] += abs(z - want) <= 0.05 and found == bool(under.size)
        ends = (px0 - z_top * ax, py0 - z_top * ay, px0 - z_bot * ax, py0 - z_bot * ay)
        if all(0.0 <= e <= 95.0 for e in ends):  # inside the window: the exact walk
            z, found = relief_march.first_hit(v, cells, tops, px0, py0, ax, ay, z_top, z_bot)
            inside += 1
            agree["exact"] += abs(z - want) <= 0.05 and found == bool(under.size)
    assert agree["tiles"] >= 0.97 * n, agree
    assert agree["tiles"] >= agree["no tiles"] - 0.005 * n, agree
    # The exact walk differs only where a ray grazes a block between two samples.
    assert inside > 0.2 * n
    assert agree["exact"] >= 0.99 * inside, (agree, inside)


def test_relief_frames_are_the_same_bytes_when_the_kernels_are_compiled_anew() -> None:
    """A process where numba finds no writable cache directory compiles the kernels itself
    (no failure) and renders the same bytes as this one (cached machine code, or not)."""
    code = (
        "import hashlib, sys, math\n"
        "import numba.core.caching as c\n"
        "c.CacheImpl._locator_classes = []  # as where nothing is writable\n"
        "from air_sitl.camera.model import CameraModel\n"
        "from air_sitl.camera.render import Renderer, pose_state\n"
        "from air_sitl.maps.open import open_map, open_surface\n"
        "from air_sitl.state import GeoPoint\n"
        f"home = GeoPoint(lat_deg={HOME.lat_deg!r}, lon_deg={HOME.lon_deg!r}, "
        f"alt_amsl_m={HOME.alt_amsl_m!r})\n"
        "m = open_map('urban', home, seed=3)\n"
        "r = Renderer(m, CameraModel(), seed=3, surface=open_surface('builtin', m))\n"
        "s = pose_state(home.lat_deg, home.lon_deg, home.alt_amsl_m + 180.0, alt_agl_m=180.0,"
        " roll_rad=0.2, pitch_rad=0.05, yaw_rad=1.0)\n"
        "print(hashlib.sha256(r.render(s, noise_index=0).tobytes()).hexdigest())\n"
    )
    fresh = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout.strip()
    m = open_map("urban", HOME, seed=3)
    r = Renderer(m, CameraModel(), seed=3, surface=open_surface("builtin", m))
    s = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + 180.0, alt_agl_m=180.0,
        roll_rad=0.2, pitch_rad=0.05, yaw_rad=1.0,
    )  # fmt: skip
    assert hashlib.sha256(r.render(s, noise_index=0).tobytes()).hexdigest() == fresh


@pytest.mark.parametrize(("kind", "alt_m", "roll_deg"), [("urban", 300.0, 4.0),
                                                         ("forest", 3000.0, 10.0)])  # fmt: skip
def test_relief_frames_in_strips_are_one_remap_of_the_whole_window(
    kind: str, alt_m: float, roll_deg: float
) -> None:
    """The relief path remaps strip by strip, each from a copy of the map pixels its strip
    samples: the same bytes as one remap of the whole mosaic, and every map point of a
    strip inside that strip's bounds."""
    m = open_map(kind, HOME, seed=1)
    r = Renderer(m, CameraModel(noise_sigma=0.0), seed=1, surface=open_surface("builtin", m))
    state = _pose(HOME.alt_amsl_m + alt_m, roll_deg=roll_deg)
    got = r.render(state)
    g = r.geometry(state)
    assert r._remap is not None
    rp, cam, rows = r._remap, r.camera, r._strip_rows
    rot, jac, cx, cy = rp.relief_setup(state, g.level)
    window = rp.relief_window(state, g, rot, jac, cx, cy)
    maps, bounds = relief_mod.ground_maps(
        window, rot, jac, g.level, cx, cy, state.alt_amsl_m, cam.width_px, cam.height_px, rows
    )
    assert rows < cam.height_px and len(bounds) == -(-cam.height_px // rows)
    for k, b in enumerate(bounds):
        part = maps[k * rows : (k + 1) * rows]
        assert b[0] <= part[:, :, 0].min() and part[:, :, 0].max() <= b[2]
        assert b[1] <= part[:, :, 1].min() and part[:, :, 1].max() <= b[3]
    wh, ww = window.values.shape
    mosaic, mx, my = r._mosaic(g.level, window.x0, window.y0, window.x0 + ww - 1,
                               window.y0 + wh - 1)  # fmt: skip
    shift = np.array([window.x0 - mx, window.y0 - my], dtype=np.float32)
    whole = cv2.remap(mosaic, maps + shift, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                      borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))  # fmt: skip
    assert np.array_equal(got, cv2.cvtColor(whole, cv2.COLOR_BGRA2BGR))


_WARM_CHECK = """
import math
from air_sitl.camera import relief
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.open import open_map, open_surface
from georef_helpers import HOME

entry = ("tile_max", "cell_max", "first_hit", "hit_maps")
m = open_map("urban", HOME)
renderer = Renderer(m, CameraModel(), surface=open_surface("builtin", m))
k = relief._kernels()
built = [len(getattr(k, n).signatures) for n in entry]
for alt, roll in ((200.0, 0.0), (300.0, 15.0)):
    renderer.render(pose_state(HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m + alt, alt_agl_m=alt,
                               roll_rad=math.radians(roll), pitch_rad=0.02, yaw_rad=0.3))
print(built, [len(getattr(k, n).signatures) for n in entry])
"""


def test_a_relief_renderer_compiles_its_kernels_when_built_not_at_a_frame() -> None:
    """The kernels are compiled (or loaded from numba's cache) when the renderer is built,
    before any clock runs, each once: frames over relief never compile (a real-time serve
    would stall its first frames for seconds after an install). A fresh process: this one
    may have compiled them already. Where numba's JIT compiles them (the machine code built
    ahead of time has nothing left to compile)."""
    tests = Path(__file__).resolve().parents[1]  # where georef_helpers is
    out = subprocess.run(
        [sys.executable, "-c", _WARM_CHECK], capture_output=True, text=True, check=True,
        cwd=tests, env={**os.environ, "AIR_SITL_JIT": "1"},
    )  # fmt: skip
    built, after = out.stdout.strip().split("] [")
    assert built == "[1, 1, 1, 1" and after == "1, 1, 1, 1]", out.stdout
