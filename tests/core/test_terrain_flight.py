"""Flights over relief (``--dem``): take-off from the ground at home, plan altitudes by their
frames (relative to home, AMSL, above the terrain), ``agl_m`` in frames.csv, and a plan flown
into a hill ends ``crashed``. Real JSBSim flights through ``fly``, over synthetic DEM
GeoTIFFs written by rasterio (geographic CRS, the map's is UTM)."""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pytest
import rasterio
import short_plans
from rasterio.transform import Affine

from air_sitl.cli import main
from air_sitl.dataset.air_schema import FRAMES_COLUMNS
from air_sitl.frames import WGS84_A_M
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)  # the plan's planned home
M_PER_DEG_LAT = math.radians(1.0) * WGS84_A_M
M_PER_DEG_LON = M_PER_DEG_LAT * math.cos(math.radians(HOME.lat_deg))
BASE_M = 150.0  # the DEM's ground away from the relief
Relief = Callable[[npt.NDArray[np.float64], npt.NDArray[np.float64]], npt.NDArray[np.float64]]


def north_east(lat_deg: Any, lon_deg: Any) -> tuple[Any, Any]:
    """Metres north and east of HOME (the flat-earth frame the DEMs are drawn in)."""
    return (
        (np.asarray(lat_deg) - HOME.lat_deg) * M_PER_DEG_LAT,
        (np.asarray(lon_deg) - HOME.lon_deg) * M_PER_DEG_LON,
    )


def latlon(north_m: float, east_m: float) -> tuple[float, float]:
    return HOME.lat_deg + north_m / M_PER_DEG_LAT, HOME.lon_deg + east_m / M_PER_DEG_LON


def write_dem(path: Path, relief: Relief, half_m: float = 4000.0, px_m: float = 10.0) -> Path:
    """A float32 DEM in EPSG:4326 around HOME: heights ``relief(north_m, east_m)`` AMSL."""
    dlat, dlon = px_m / M_PER_DEG_LAT, px_m / M_PER_DEG_LON
    rows, cols = round(2 * half_m / px_m), round(2 * half_m / px_m)
    west, north = HOME.lon_deg - half_m / M_PER_DEG_LON, HOME.lat_deg + half_m / M_PER_DEG_LAT
    lon = west + (np.arange(cols) + 0.5) * dlon
    lat = north - (np.arange(rows) + 0.5) * dlat
    n, e = north_east(lat[:, None], lon[None, :])
    heights = relief(n + 0 * e, e + 0 * n).astype(np.float32)
    with rasterio.open(
        path, "w", driver="GTiff", width=cols, height=rows, count=1, dtype="float32",
        crs="EPSG:4326", transform=Affine(dlon, 0.0, west, 0.0, -dlat, north),
    ) as dst:  # fmt: skip
        dst.write(heights, 1)
    return path


def write_plan(path: Path, items: list[tuple[int, int, float, float, float]]) -> Path:
    """(command, frame, north m, east m, altitude m) items; planned home at HOME (120 m)."""
    placed = [(cmd, frame, *latlon(n, e), alt) for cmd, frame, n, e, alt in items]
    return short_plans.write_items_plan(path, HOME, placed)


def fly(plan: Path, dem: Path, out: Path, *extra: str) -> tuple[int, dict[str, Any]]:
    code = main(["fly", str(plan), "--dem", str(dem), "--out", str(out), "--quiet", "--nav",
                 "truth", "--sensor-noise", "0", "--max-sim-time", "600", *extra])  # fmt: skip
    return code, json.loads((out / "summary.json").read_text())


def trajectory(out: Path) -> dict[str, npt.NDArray[np.float64]]:
    with (out / "trajectory.csv").open() as f:
        rows = list(csv.DictReader(f))
    keys = ("sim_time_ns", "lat_deg", "lon_deg", "alt_amsl_m", "mission_seq")
    return {k: np.array([float(r[k]) for r in rows]) for k in keys}


def plateau(n: Any, e: Any) -> Any:
    """A 300 m plateau 1.5 km across around home, falling to BASE_M beyond 2 km."""
    r = np.hypot(n, e)
    return BASE_M + (300.0 - BASE_M) * np.clip((2000.0 - r) / 500.0, 0.0, 1.0)


def test_take_off_from_home_on_a_plateau_and_relative_altitudes_above_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    dem = write_dem(tmp_path / "plateau.tif", plateau)
    plan = write_plan(tmp_path / "UP.plan", [(22, 3, 0, 0, 40), (16, 3, 600, 0, 60)])
    code, s = fly(plan, dem, tmp_path / "out", "--no-camera")
    err = capsys.readouterr().err
    assert code == 0 and s["crashed"] is None and s["mission_completed"] is True, (s, err)
    # The plan says 120 m; the vehicle stands on the DEM's 300 m, and says so.
    assert "home altitude 120.0 m AMSL, the ground there is at 300.0 m" in err, err
    t = trajectory(tmp_path / "out")
    assert 300.0 <= t["alt_amsl_m"][0] < 302.0  # on its wheels, the CG a little above ground
    # NAV_TAKEOFF 40 m and the waypoint's 60 m are above that ground (PX4's home: where the
    # vehicle is), not above the plan's 120 m.
    at_wp = t["alt_amsl_m"][t["mission_seq"] == 1]
    assert abs(at_wp[-1] - 360.0) < 10.0, at_wp[-1]


def ridge(n: Any, e: Any) -> Any:
    """An east-west ridge 60 m high (Gaussian, sigma 250 m) 1.5 km north of home."""
    return BASE_M + 60.0 * np.exp(-0.5 * ((n - 1500.0) / 250.0) ** 2) + 0.0 * e


@pytest.mark.parametrize("frame", [10, 11], ids=["TERRAIN_ALT", "TERRAIN_ALT_INT"])
def test_a_terrain_alt_leg_over_a_ridge_keeps_its_height_above_the_terrain(
    tmp_path: Path, frame: int
) -> None:
    dem = write_dem(tmp_path / "ridge.tif", ridge)
    plan = write_plan(
        tmp_path / "UR.plan",
        [(22, 3, 0, 0, 40), (16, frame, 300, 0, 100), (16, frame, 2700, 0, 100)],
    )
    code, s = fly(plan, dem, tmp_path / "out", "--no-camera", "--air-start")
    assert code == 0 and s["crashed"] is None, s
    t = trajectory(tmp_path / "out")
    n, e = north_east(t["lat_deg"], t["lon_deg"])
    agl = t["alt_amsl_m"] - ridge(n, e)
    leg = (n > 500.0) & (n < 2500.0)
    assert leg.sum() > 100
    # 100 m above the terrain all along the leg, within a fifth of it, while the ground under
    # the aircraft rises 60 m and falls again: the aircraft climbs over the ridge.
    low, high = agl[leg].min(), agl[leg].max()
    assert low > 80.0 and high < 120.0, (low, high)
    crest = np.abs(n - 1500.0) < 50.0
    before = np.abs(n - 600.0) < 50.0
    assert t["alt_amsl_m"][crest].mean() - t["alt_amsl_m"][before].mean() > 40.0


def hill(n: Any, e: Any) -> Any:
    """A hill 150 m high (Gaussian, sigma 200 m) 1.5 km north of home."""
    return BASE_M + 150.0 * np.exp(-0.5 * (((n - 1500.0) ** 2 + e**2) / 200.0**2))


def test_a_plan_flown_into_a_hill_ends_crashed_where_it_hit(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "hill.tif", hill)
    # 60 m above home (home on the DEM: 150 m), so 210 m AMSL: below the 300 m hill top.
    plan = write_plan(
        tmp_path / "UH.plan", [(22, 3, 0, 0, 40), (16, 3, 300, 0, 60), (16, 3, 2700, 0, 60)]
    )
    code, s = fly(plan, dem, tmp_path / "out", "--no-camera", "--air-start")
    assert code == 1
    assert s["mission_completed"] is False and s["landed"] is False
    crash = s["crashed"]
    assert crash is not None and "ground contact outside a landing" in crash["reason"], crash
    n, e = north_east(crash["lat_deg"], crash["lon_deg"])
    # Where the hill's flank reaches 210 m: 1.5 km - 200 m * sqrt(2 ln(150 / 60)), 1229 m north.
    assert abs(float(n) - 1229.0) < 60.0 and abs(float(e)) < 20.0, (n, e)
    assert abs(crash["surface_amsl_m"] - float(hill(n, e))) < 1.0
    assert abs(crash["alt_amsl_m"] - crash["surface_amsl_m"]) < 1.0
    # The flight stopped there: nothing flown after the crash.
    assert s["sim_time_s"] == pytest.approx(crash["sim_time_s"], abs=0.01)


def slope(n: Any, e: Any) -> Any:
    """Ground rising 5 % to the north: under the capture leg (300 m north) 15 m above home's."""
    return BASE_M + 0.05 * n + 0.0 * e


def test_frames_csv_ends_with_the_height_above_the_surface(tmp_path: Path) -> None:
    dem = write_dem(tmp_path / "slope.tif", slope)
    plan = short_plans.write_short_plan(tmp_path / "US-200.plan", HOME, leg_m=20.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--dem", str(dem), "--out", str(out), "--quiet",
                 "--air-start", "--nav", "truth", "--noise-sigma", "0"])  # fmt: skip
    assert code == 0
    with (out / "frames.csv").open() as f:
        header = f.readline().strip().split(",")
        rows = list(csv.DictReader(f, fieldnames=header))
    assert header[-1] == "agl_m" and tuple(header[:-1]) == FRAMES_COLUMNS
    assert len(rows) > 30
    for row in rows:
        n, e = north_east(float(row["lat_deg"]), float(row["lon_deg"]))
        alt = float(row["alt_amsl_m"])
        assert float(row["agl_m"]) == pytest.approx(alt - float(slope(n, e)), abs=0.3)
        # RelativeAltitude stays above home (on the DEM: 150 m), not above the ground here.
        assert float(row["alt_rel_m"]) == pytest.approx(alt - BASE_M, abs=0.01)
    assert main(["check", str(out)]) == 0


def terrace(dz_m: float) -> Relief:
    """Home's ground (BASE_M) out to 1 km north, then ``dz_m`` higher or lower beyond 1.5 km."""

    def relief(n: Any, e: Any) -> Any:
        return BASE_M + dz_m * np.clip((n - 1000.0) / 500.0, 0.0, 1.0) + 0.0 * e

    return relief


@pytest.mark.parametrize("dz_m", [-30.0, 25.0], ids=["valley", "terrace"])
def test_a_landing_away_from_home_flares_above_the_ground_there(
    tmp_path: Path, dz_m: float
) -> None:
    # PX4 with a terrain estimate flares on the height above the ground under it; the DEM is
    # ours: the touchdown is on the ground at the NAV_LAND point, 30 m below or 25 m above
    # home's, not at home's altitude (in the air over a valley, or into a terrace).
    relief = terrace(dz_m)
    dem = write_dem(tmp_path / "terrace.tif", relief)
    plan = write_plan(
        tmp_path / "UL.plan",
        [(22, 3, 0, 0, 40), (16, 3, 300, 0, 60), (16, 3, 600, 0, 60), (21, 3, 2600, 0, 0)],
    )
    code, s = fly(plan, dem, tmp_path / "out", "--no-camera")
    assert code == 0 and s["crashed"] is None and s["landed"] is True, s
    assert s["mission_completed"] is True
    t = trajectory(tmp_path / "out")
    n, e = north_east(t["lat_deg"], t["lon_deg"])
    height = t["alt_amsl_m"] - relief(n, e)
    # It came down on the terrace/valley floor, near the NAV_LAND point, and stopped there.
    assert n[-1] > 1600.0 and abs(n[-1] - 2600.0) < 400.0, n[-1]
    assert height[-1] < 2.0, height[-1]
    # A flare, not a fall: the sink rate over the last 2 s before the wheels touched was gentle.
    sink = -np.diff(t["alt_amsl_m"]) / (np.diff(t["sim_time_ns"]) * 1e-9)
    air = np.flatnonzero(height[1:] > 1.0)
    last_air = air[-1]
    window = (t["sim_time_ns"][1:] > t["sim_time_ns"][last_air] - 2e9) & (
        np.arange(len(sink)) <= last_air
    )
    assert sink[window].max() < 2.5, sink[window].max()
