"""The renderer measures how much of each frame shows a GeoTIFF's nodata or ground off the map,
from the alpha of the pixels it sampled, without changing a byte of the frame.

Real GeoTIFFs written here with rasterio: an 800 m square at 1 m/px with a 10 m wide nodata
stripe running north-south 60-70 m east of home. The camera looks straight down from 200 m
heading north (image x = east), so a frame spans 2 * 200 * 320 / fx = 217 m east-west and the
stripe's share of it follows from the geometry alone.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from georef_helpers import HOME, latlon_to_px, marks_image, utm_grid, write_tif

from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.cli import main
from air_sitl.frames import ned2geodetic
from air_sitl.maps.geotiff import GeoTiffMap

ALT_M = 200.0
STRIPE_M = (60.0, 70.0)  # east of home


def _maps(folder: Path) -> tuple[Path, Path, float]:
    """(map with the nodata stripe, the same pixels untagged, east edge of the map in m)."""
    crs, transform, size = utm_grid(HOME, 1.0, 400.0)
    img, _ = marks_image(size, 1.0, 20.0, 1.5)  # grey 40..200: never the nodata value 0
    col, _row = latlon_to_px(crs, transform, HOME.lat_deg, HOME.lon_deg)
    c0 = round(col + 0.5 + STRIPE_M[0])  # pixel c covers east offsets [c - col - 0.5, + 1)
    img[:, c0 : c0 + round(STRIPE_M[1] - STRIPE_M[0])] = 0
    tagged = write_tif(folder / "stripe.tif", img, crs, transform, nodata=0)
    plain = write_tif(folder / "plain.tif", img, crs, transform)
    return tagged, plain, size - 0.5 - col


@pytest.fixture(scope="module")
def maps(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, float]:
    return _maps(tmp_path_factory.mktemp("nodata"))


def _renderer(path: Path) -> Renderer:
    return Renderer(GeoTiffMap(path, ground_elevation_m=HOME.alt_amsl_m), CameraModel(), seed=3)


def _pose(east_m: float) -> object:
    lat, lon, _ = ned2geodetic(0.0, east_m, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
    return pose_state(lat, lon, HOME.alt_amsl_m + ALT_M, alt_agl_m=ALT_M)


def _half_width_m() -> float:
    cam = CameraModel()
    return ALT_M * (cam.width_px / 2.0) / cam.fx_px


def _expected_share(east_m: float, lo_m: float, hi_m: float) -> float:
    """Share of the frame between east offsets lo and hi (whole image height)."""
    hw = _half_width_m()
    seen = max(0.0, min(hi_m, east_m + hw) - max(lo_m, east_m - hw))
    return seen / (2.0 * hw)


# 2 image columns of tolerance: the stripe's edges fall between pixels (alpha 128 threshold).
TOL = 2.0 / 640.0


@pytest.mark.parametrize("east_m", [-120.0, -40.0, 0.0, 100.0, 170.0, 185.0])
def test_the_nodata_share_is_the_stripe_seen(maps: tuple[Path, Path, float], east_m: float) -> None:
    tagged, _plain, _edge = maps
    r = _renderer(tagged)
    img = r.render(_pose(east_m))  # type: ignore[arg-type]
    share = r.nodata_fraction()
    expected = _expected_share(east_m, *STRIPE_M)
    assert share == pytest.approx(expected, abs=TOL), (east_m, share, expected)
    if expected == 0.0:
        assert share == 0.0
    # Independent of the alpha: the stripe's pixels are black in the image, the rest >= 40;
    # a map pixel spans 2.9 image pixels, so each edge blends over about one more column.
    dark = np.count_nonzero(img.max(axis=2) < 20) / (img.shape[0] * img.shape[1])
    assert share == pytest.approx(dark, abs=2 * TOL)


def test_ground_off_the_map_counts_as_well(maps: tuple[Path, Path, float]) -> None:
    _tagged, plain, edge_m = maps
    r = _renderer(plain)
    for east_m in (edge_m - 50.0, edge_m - 200.0):
        r.render(_pose(east_m))  # type: ignore[arg-type]
        expected = _expected_share(east_m, edge_m, edge_m + 1e6)
        assert r.nodata_fraction() == pytest.approx(expected, abs=TOL), east_m
    assert expected == 0.0 and r.nodata_fraction() == 0.0


def test_the_nodata_tag_changes_no_byte_of_the_frames(maps: tuple[Path, Path, float]) -> None:
    tagged, plain, _edge = maps
    with_tag, without = _renderer(tagged), _renderer(plain)
    for i, east_m in enumerate((-40.0, 30.0, 100.0)):
        s = _pose(east_m)
        a = with_tag.frame_jpeg(s, i)  # type: ignore[arg-type]
        b = without.frame_jpeg(s, i)  # type: ignore[arg-type]
        assert a == b
        assert with_tag.nodata_fraction() > 0.0
        assert without.nodata_fraction() == 0.0  # untagged black is just black


def test_render_says_the_share_of_its_frame(
    maps: tuple[Path, Path, float], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tagged, plain, _edge = maps
    for tif, said in ((tagged, True), (plain, False)):
        out = tmp_path / f"{tif.stem}.jpg"
        code = main(["render", "--map", str(tif), "--lat", str(HOME.lat_deg), "--lon",
                     str(HOME.lon_deg), "--alt-agl", str(ALT_M), "--out", str(out)])  # fmt: skip
        err = capsys.readouterr().err
        assert code == 0 and out.is_file()
        found = re.search(rf"map {tif.name}: ([0-9.]+) % of the frame shows nodata or ground "
                          "off the map", err)  # fmt: skip
        assert (found is not None) == said and ("nodata" in err) == said, err
        if found is not None:
            share = float(found.group(1)) / 100.0
            assert share == pytest.approx(_expected_share(0.0, *STRIPE_M), abs=TOL + 0.0005)


@pytest.mark.parametrize("names", [("vignette",), ("distortion", "blur")])
def test_frames_with_camera_effects_are_measured_too(
    maps: tuple[Path, Path, float], names: tuple[str, ...]
) -> None:
    tagged, _plain, _edge = maps
    camera = CameraModel(effects=CameraEffects(enabled=names))
    r = Renderer(GeoTiffMap(tagged, ground_elevation_m=HOME.alt_amsl_m), camera, seed=3)
    r.render(_pose(0.0))  # type: ignore[arg-type]
    # Distortion (about 8 px at the corners) moves the stripe's edges by a pixel or two.
    assert r.nodata_fraction() == pytest.approx(_expected_share(0.0, *STRIPE_M), abs=2 * TOL)
    r.render(_pose(-120.0))  # type: ignore[arg-type]
    assert r.nodata_fraction() == 0.0
