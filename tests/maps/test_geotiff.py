"""GeoTIFF maps: same renders as in-memory pixels, overviews, dates, every bad input."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from georef_helpers import HOME, utm_grid, write_tif
from rasterio.transform import Affine
from vehicle_states import above

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.errors import MapError
from air_sitl.frames import ned2geodetic
from air_sitl.maps.array import ArrayMap
from air_sitl.maps.open import default_map_for_plan, open_map
from air_sitl.state import GeoPoint


def _texture(size: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    small = rng.integers(0, 256, (size // 8 + 1, size // 8 + 1, 3), dtype=np.uint8)
    big = np.repeat(np.repeat(small, 8, 0), 8, 1)[:size, :size]
    return np.clip(big.astype(np.int16) + rng.integers(-30, 30, big.shape), 0, 255).astype(np.uint8)


@pytest.fixture(scope="module")
def texture_tif(
    tmp_path_factory: pytest.TempPathFactory,
) -> tuple[Path, np.ndarray, str, tuple[float, ...]]:
    crs, transform, size = utm_grid(HOME, 1.0, 1500.0)
    img = _texture(size, 1)
    path = write_tif(tmp_path_factory.mktemp("tif") / "texture.tif", img, crs, transform)
    return path, img, crs, transform


@pytest.mark.parametrize(("alt", "roll"), [(300.0, 15.0), (2500.0, 0.0)])
def test_geotiff_renders_exactly_like_the_same_pixels_in_memory(
    texture_tif, alt: float, roll: float
) -> None:  # type: ignore[no-untyped-def]
    path, img, crs, transform = texture_tif
    tif = open_map(str(path), HOME)
    mem = ArrayMap(img, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    state = above(HOME, alt, roll_rad=math.radians(roll), pitch_rad=0.05, yaw_rad=1.0)
    cam = CameraModel()
    a = Renderer(tif, cam, seed=4).frame_jpeg(state, 7)
    b = Renderer(mem, cam, seed=4).frame_jpeg(state, 7)
    assert a == b
    assert tif.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg) == mem.latlon_to_map_px(
        HOME.lat_deg, HOME.lon_deg
    )


def test_file_overviews_serve_as_pyramid(tmp_path: Path, texture_tif) -> None:  # type: ignore[no-untyped-def]
    path, _img, _crs, _transform = texture_tif
    ovr = tmp_path / "ovr.tif"
    ovr.write_bytes(path.read_bytes())
    with rasterio.open(ovr, "r+") as dst:
        dst.build_overviews([2, 4], rasterio.enums.Resampling.average)
    tif = open_map(str(ovr), HOME)
    t2 = tif.tile(2, 1, 1)  # type: ignore[attr-defined]
    with rasterio.open(ovr, overview_level=1) as src:
        data = src.read(window=rasterio.windows.Window(256, 256, 256, 256))
    assert np.array_equal(t2[:, :, 2], data[0])
    assert tif.describe()["sha256"] and len(tif.describe()["sha256"]) == 64  # type: ignore[index]


def test_geographic_crs_is_handled(tmp_path: Path) -> None:
    # The same place in EPSG:4326: the marks and the centre still land right.
    size = 1000
    d = 0.00002
    lon0, lat0 = HOME.lon_deg - size / 2 * d, HOME.lat_deg + size / 2 * d
    img = _texture(size, 2)
    path = tmp_path / "geo.tif"
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=size,
        height=size,
        count=3,
        dtype="uint8",
        crs="EPSG:4326",
        transform=Affine(d, 0, lon0, 0, -d, lat0),
    ) as dst:
        dst.write(img[:, :, ::-1].transpose(2, 0, 1))
    m = open_map(str(path), HOME)
    x, y = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    assert abs(x - (size / 2 - 0.5)) < 1e-6 and abs(y - (size / 2 - 0.5)) < 1e-6
    state = above(HOME, 150.0, pitch_rad=0.3)
    cam = CameraModel(noise_sigma=0.0)
    renderer = Renderer(m, cam)
    frame = renderer.render(state)
    assert (frame.astype(int).sum(axis=2) > 0).mean() > 0.99
    # Nose up 0.3 rad, heading north: the belly camera looks 150 * tan(0.3) m ahead (north).
    ahead_m = 150.0 * math.tan(0.3)
    lat_c, lon_c, _ = ned2geodetic(ahead_m, 0.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    got = renderer.map_xy_px(state)
    assert got is not None
    assert (
        math.hypot(got[0] - ((lon_c - lon0) / d - 0.5), got[1] - ((lat0 - lat_c) / d - 0.5)) < 1.0
    )


def test_dates_list_picks_files(tmp_path: Path, texture_tif) -> None:  # type: ignore[no-untyped-def]
    path, img, crs, transform = texture_tif
    other = write_tif(tmp_path / "later.tif", 255 - img, crs, transform)
    spec = f"{path},{other}"
    a = open_map(spec, HOME, date=0)
    b = open_map(spec, HOME, date="1")
    c = open_map(str(path), HOME, date=str(other))
    assert a.name == "texture.tif" and b.name == "later.tif" and c.name == "later.tif"
    with pytest.raises(MapError, match="2 date file"):
        open_map(spec, HOME, date=2)


def _one_line(err: pytest.ExceptionInfo[MapError]) -> str:
    text = str(err.value)
    assert "\n" not in text
    return text


def test_bad_inputs_raise_one_line_map_errors(tmp_path: Path, texture_tif) -> None:  # type: ignore[no-untyped-def]
    path, _img, crs, transform = texture_tif
    with pytest.raises(MapError) as e:
        open_map(str(tmp_path / "missing.tif"), HOME)
    assert "missing.tif" in _one_line(e)
    with pytest.raises(MapError) as e:
        open_map("suburb", HOME)
    assert "'suburb'" in _one_line(e)
    plain = tmp_path / "plain.tif"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with rasterio.open(
            plain, "w", driver="GTiff", width=64, height=64, count=3, dtype="uint8"
        ) as dst:
            dst.write(np.zeros((3, 64, 64), np.uint8))
    with pytest.raises(MapError) as e:
        open_map(str(plain), HOME)
    assert "not georeferenced" in _one_line(e)
    text = tmp_path / "notes.tif"
    text.write_text("hello")
    with pytest.raises(MapError) as e:
        open_map(str(text), HOME)
    assert "notes.tif" in _one_line(e)
    far = GeoPoint(lat_deg=HOME.lat_deg + 1.0, lon_deg=HOME.lon_deg, alt_amsl_m=0.0)
    with pytest.raises(MapError) as e:
        open_map(str(path), far)
    assert "outside the map" in _one_line(e)
    wide = tmp_path / "u16.tif"
    with rasterio.open(
        wide,
        "w",
        driver="GTiff",
        width=64,
        height=64,
        count=3,
        dtype="uint16",
        crs=crs,
        transform=Affine(transform[1], 0, transform[0], 0, transform[5], transform[3]),
    ) as dst:
        dst.write(np.zeros((3, 64, 64), np.uint16))
    with pytest.raises(MapError) as e:
        open_map(str(wide), HOME)
    assert "uint8" in _one_line(e)
    with pytest.raises(MapError) as e:
        open_map("urban", HOME, date="1999-01-01")
    assert "1999-01-01" in _one_line(e)


def test_default_map_for_plan() -> None:
    assert default_map_for_plan("UL-200") == "urban"
    assert default_map_for_plan("missions/FC-300.plan") == "forest"
    assert default_map_for_plan("mine") == "urban"


def test_reads_after_close_reopen(texture_tif) -> None:  # type: ignore[no-untyped-def]
    path, img, _crs, _transform = texture_tif
    tif = open_map(str(path), HOME)
    tif.close()  # type: ignore[attr-defined]
    tile = tif.read_level(0, 0, 0, 16, 16)
    assert np.array_equal(tile[:, :, :3], img[:16, :16])


def test_read_ground_picks_level_and_window(texture_tif) -> None:  # type: ignore[no-untyped-def]
    path, img, _crs, transform = texture_tif
    tif = open_map(str(path), HOME)
    x0, y0 = transform[0] + 100.0, transform[3] - 100.0  # 100 m in from the corner
    patch = tif.read_ground(x0, y0, x0 + 400.0, y0 - 300.0, gsd_m=4.2)
    assert patch.level == 2  # 4 m pixels: the coarsest level not coarser than 4.2 m
    assert (patch.x0_px, patch.y0_px) == (24, 24)
    assert patch.image.shape[1] >= 100 and patch.image.shape[0] >= 75
    full = tif.read_ground(x0, y0, x0 + 40.0, y0 - 30.0, gsd_m=0.5)
    assert full.level == 0
    assert np.array_equal(full.image[1:31, 1:41, :3], img[100:130, 100:140])
