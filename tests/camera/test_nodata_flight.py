"""``fly`` over a GeoTIFF with a nodata stripe says which frames show it, on stderr and in
summary.json's ``frames_with_nodata``; over a fully covered map it says nothing.

Real JSBSim flights (``--air-start``, a 100 m capture leg east at 200 m, about 330 frames) over
rasterio GeoTIFFs written here: a 1 km square at 1 m/px, grey 40..200, with a 10 m wide
black stripe running north-south 150-160 m east of home, tagged nodata (value 0) in one file
and untagged in the other. The frames that really show the stripe are read back from the
archive's JPEGs (black pixels), independently of the renderer's count.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
from pathlib import Path

import cv2
import numpy as np
import pytest
import rasterio
from georef_helpers import HOME, latlon_to_px, marks_image, utm_grid, write_tif
from rasterio.transform import Affine
from short_plans import write_short_plan

from air_sitl.builder import build_flight, load_setup, open_camera, open_setup_map
from air_sitl.camera.model import CameraModel
from air_sitl.cli import main
from air_sitl.clock import NS_PER_S
from air_sitl.maps.utm import latlon2utm, utm_zone_of
from air_sitl.options import FlightOptions, MapChoice
from air_sitl.recording import CaptureRecorder

pytestmark = pytest.mark.integration

STRIPE_M = (150.0, 160.0)  # east of home; the capture leg runs east from 0 to 100 m


@pytest.fixture(scope="module")
def maps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("nodata_flight")
    crs, transform, size = utm_grid(HOME, 1.0, 500.0)
    img, _ = marks_image(size, 1.0, 20.0, 1.5)
    col, _row = latlon_to_px(crs, transform, HOME.lat_deg, HOME.lon_deg)
    c0 = round(col + 0.5 + STRIPE_M[0])
    img[:, c0 : c0 + round(STRIPE_M[1] - STRIPE_M[0])] = 0
    return {
        "tagged": write_tif(folder / "stripe.tif", img, crs, transform, nodata=0),
        "plain": write_tif(folder / "plain.tif", img, crs, transform),
    }


def _fly(tmp_path: Path, tif: Path) -> tuple[dict[str, object], str, Path]:
    plan = write_short_plan(tmp_path / "S-200.plan", HOME, leg_m=100.0, alt_m=200.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--map", str(tif), "--out", str(out), "--quiet",
                 "--air-start", "--nav", "truth", "--render-workers", "1"])  # fmt: skip
    assert code == 0
    return json.loads((out / "summary.json").read_text()), str(out), out


@pytest.fixture(scope="module")
def tagged_flight(
    tmp_path_factory: pytest.TempPathFactory, maps: dict[str, Path]
) -> tuple[dict[str, object], str, Path]:
    """``fly`` over the tagged map, flown once for the two tests that read it: (summary.json,
    what it wrote on stderr, the archive)."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        summary, _, out = _fly(tmp_path_factory.mktemp("tagged_flight"), maps["tagged"])
    return summary, err.getvalue(), out


def _dark_shares(out: Path) -> list[float]:
    """Share of black pixels (the stripe; the map is 40..200 elsewhere) of every frame."""
    shares = []
    for jpg in sorted(out.glob("frame_*.jpg")):
        img = cv2.imread(str(jpg))
        assert img is not None
        # Pixels whose channels are all below 16 (cv2.inRange: numpy's max over the channel
        # axis took 1.7 s for a flight's 300 frames, this 0.05 s).
        black = cv2.countNonZero(cv2.inRange(img, (0, 0, 0), (15, 15, 15)))
        shares.append(float(black) / (img.shape[0] * img.shape[1]))
    return shares


def test_the_frames_showing_nodata_are_named(
    tagged_flight: tuple[dict[str, object], str, Path],
) -> None:
    summary, err, out = tagged_flight
    record = summary["frames_with_nodata"]
    assert isinstance(record, dict)
    dark = _dark_shares(out)
    n = len(dark)
    first_dark = next(i for i, s in enumerate(dark) if s > 0.0)
    assert 0 < first_dark < n - 50  # the stripe comes into view during the leg
    # One run of frames from the stripe's first appearance to the end of the window: the
    # renderer counts a pixel from half nodata on, the black test from nearly all of it (one
    # map pixel is about 3 image rows, 3 frames at 15 m/s).
    [[a, b]] = record["ranges"]
    assert b == n - 1
    assert first_dark - 6 <= a <= first_dark
    assert record["count"] == b - a + 1
    assert record["max_fraction"] == pytest.approx(max(dark), abs=0.01)
    assert 0.04 < record["max_fraction"] < 0.09  # 10 m of the 163 m along the track
    line = f"frames {a}-{b} ({b - a + 1} of {n}) show nodata or ground off the map"
    assert line in err, err
    assert err.count("nodata") == 1


def test_a_fully_covered_flight_says_nothing(
    tmp_path: Path, maps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    summary, _, out = _fly(tmp_path, maps["plain"])
    err = capsys.readouterr().err
    assert "frames_with_nodata" not in summary
    assert "nodata" not in err and "off the map" not in err
    assert max(_dark_shares(out)) > 0.04  # the same black stripe, but it is data here


# A flat DEM (2 m pixels, the map's UTM CRS) from 100 m west to 120 m east of home and from
# 100 m south to 450 m north, with a nodata hole at 30-60 m east, 250-350 m north: the
# capture leg (300 m north, east from 0 to 100 m, then on to 160 m) crosses the hole and
# leaves the DEM at 120 m east.
DEM_WEST_M, DEM_EAST_M, DEM_SOUTH_M, DEM_NORTH_M = -100.0, 120.0, -100.0, 450.0
HOLE_M = (30.0, 60.0, 250.0, 350.0)  # east from, to; north from, to


def _write_dem(path: Path, *, hole: bool, east_m: float) -> tuple[Path, float, float]:
    """The DEM; (UTM easting, northing) of home."""
    zone = utm_zone_of(HOME.lat_deg, HOME.lon_deg)
    e_home, n_home = latlon2utm(HOME.lat_deg, HOME.lon_deg, zone)
    cols, rows = round((east_m - DEM_WEST_M) / 2), round((DEM_NORTH_M - DEM_SOUTH_M) / 2)
    heights = np.full((rows, cols), HOME.alt_amsl_m, dtype=np.float32)
    if hole:
        e0, e1, n0, n1 = HOLE_M
        heights[round((DEM_NORTH_M - n1) / 2) : round((DEM_NORTH_M - n0) / 2),
                round((e0 - DEM_WEST_M) / 2) : round((e1 - DEM_WEST_M) / 2)] = -9999.0  # fmt: skip
    transform = Affine(2.0, 0.0, e_home + DEM_WEST_M, 0.0, -2.0, n_home + DEM_NORTH_M)
    with rasterio.open(path, "w", driver="GTiff", width=cols, height=rows, count=1,
                       dtype="float32", crs=f"EPSG:{zone.epsg}", transform=transform,
                       nodata=-9999.0) as dst:  # fmt: skip
        dst.write(heights, 1)
    return path, e_home, n_home


def _fly_dem(tmp_path: Path, tif: Path, dem: Path) -> Path:
    plan = write_short_plan(tmp_path / "D-200.plan", HOME, leg_m=100.0, alt_m=200.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--map", str(tif), "--dem", str(dem), "--out", str(out),
                 "--quiet", "--air-start", "--nav", "truth", "--render-workers", "1"])  # fmt: skip
    assert code == 0
    return out


def test_a_dem_short_of_the_flight_and_its_holes_are_said(
    tmp_path: Path, maps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    dem, e_home, n_home = _write_dem(tmp_path / "dem.tif", hole=True, east_m=DEM_EAST_M)
    out = _fly_dem(tmp_path, maps["plain"], dem)
    err = capsys.readouterr().err
    # Truth at whole seconds from trajectory.csv, placed on the DEM's UTM grid.
    zone = utm_zone_of(HOME.lat_deg, HOME.lon_deg)
    with (out / "trajectory.csv").open() as f:
        rows = [r for r in csv.DictReader(f) if int(r["sim_time_ns"]) % 1_000_000_000 == 0]
    beyond, over_hole = [], []
    for r in rows:
        e, n = latlon2utm(float(r["lat_deg"]), float(r["lon_deg"]), zone)
        e, n = e - e_home, n - n_home
        if e >= DEM_EAST_M:
            beyond.append(r)
        elif HOLE_M[0] <= e < HOLE_M[1] and HOLE_M[2] <= n < HOLE_M[3]:
            over_hole.append(r)
    assert beyond and over_hole  # the flight does both
    for what, found in (
        ("flew beyond the DEM", beyond),
        ("flew over nodata in the DEM", over_hole),
    ):
        first = found[0]
        line = (
            f"--dem {dem.name}: the aircraft {what} for {len(found)} of {len(rows)} s (first at "
            f"{int(first['sim_time_ns']) / 1e9:.0f} s, {float(first['lat_deg']):.6f}, "
            f"{float(first['lon_deg']):.6f})"
        )
        assert line in err, err
    # The DEM's holes, once, though the flight opens the file three times.
    assert err.count(f"--dem {dem}: nodata holes in the DEM, filled from the neighbours") == 1
    # The frames' ground reaches past the east edge 82 m before the aircraft does.
    assert f"--dem {dem.name}: frames saw ground beyond the DEM for " in err


def test_a_dem_covering_the_flight_says_nothing(
    tmp_path: Path, maps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    dem, _, _ = _write_dem(tmp_path / "dem.tif", hole=False, east_m=400.0)
    _fly_dem(tmp_path, maps["plain"], dem)
    err = capsys.readouterr().err
    assert "--dem" not in err and "nodata" not in err, err


def test_serve_recordings_name_the_frames_too(
    tmp_path: Path,
    maps: dict[str, Path],
    tagged_flight: tuple[dict[str, object], str, Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``serve --out``'s recorder (one archive per capture window), on the same flight that
    ``fly`` records above, flown here without a MAVLink client (the mission starts itself)."""
    plan = write_short_plan(tmp_path / "S-200.plan", HOME, leg_m=100.0, alt_m=200.0)
    setup = load_setup(
        plan,
        FlightOptions(air_start=True, nav="truth"),
        camera=CameraModel(),
        map=MapChoice(spec=str(maps["tagged"])),
        render_workers=1,
    )
    recorder = CaptureRecorder(tmp_path / "served", setup)
    flight = build_flight(setup, sinks=[recorder], camera=open_camera(setup, open_setup_map(setup)))
    flight.run(stop=lambda s: s.autopilot.mission_completed, max_sim_time_ns=120 * NS_PER_S)
    flown = tagged_flight[0]
    [folder] = recorder.archives
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["frames_with_nodata"] == flown["frames_with_nodata"]
    assert f"show nodata or ground off the map: up to 6.1 % of the frame (in {folder})" in (
        capsys.readouterr().err
    )
