"""Rows of a real archive (JSBSim flight through ``fly``) against independent truths:

- frames.csv ENU columns against its NED columns (east = ned_east, north = ned_north,
  up = -ned_down), and up against the altitude columns (alt_amsl - home altitude);
- the GNSS fix recorded with each frame is the latest one: a frame on the fix grid records
  that very fix, and ``gps_time_ns <= sim_time_ns < gps_time_ns + period`` on every row, the
  period measured from the fixes themselves.
"""

from __future__ import annotations

import csv
import itertools
import json
import math

import pytest
import short_plans

from air_sitl.cli import main
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


@pytest.fixture(scope="module")
def rows(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, str]]:
    base = tmp_path_factory.mktemp("rows")
    plan = short_plans.write_short_plan(base / "UT-300.plan", HOME, leg_m=60.0, leg="north")
    out = base / "a"
    assert main(["fly", str(plan), "--out", str(out), "--air-start", "--quiet"]) == 0
    assert json.loads((out / "summary.json").read_text())["capture_frames"] > 100
    with (out / "frames.csv").open(newline="") as f:
        return list(csv.DictReader(f))


def test_enu_columns_agree_with_ned_columns_and_altitude(rows: list[dict[str, str]]) -> None:
    for row in rows:
        where = f"frame {row['frame']}"
        e, n, u = float(row["east_m"]), float(row["north_m"]), float(row["up_m"])
        ned_n, ned_e, ned_d = (float(row[k]) for k in ("ned_north_m", "ned_east_m", "ned_down_m"))
        assert e == pytest.approx(ned_e, abs=1e-3), where
        assert n == pytest.approx(ned_n, abs=1e-3), where
        assert u == pytest.approx(-ned_d, abs=1e-3), where
        # Up is height above home: the altitude columns say the same (curvature < 0.1 m here).
        assert u == pytest.approx(float(row["alt_amsl_m"]) - HOME.alt_amsl_m, abs=0.1), where
        assert u > 100.0, where  # the plan flies 200 m above home


def test_each_frame_records_the_latest_gnss_fix(rows: list[dict[str, str]]) -> None:
    with_fix = [r for r in rows if r["gps_time_ns"] not in ("", "nan")]
    assert len(with_fix) == len(rows)  # no denial in this flight
    fixes = sorted({int(r["gps_time_ns"]) for r in with_fix})
    period = min(b - a for a, b in itertools.pairwise(fixes))
    assert period == 200_000_000  # SPEC: GNSS at 5 Hz; measured here from the fixes
    on_grid = 0
    for r in with_fix:
        t, g = int(r["sim_time_ns"]), int(r["gps_time_ns"])
        assert g <= t < g + period, f"frame {r['frame']}: fix at {g} for a frame at {t}"
        if t % period == 0:
            on_grid += 1
            assert g == t, f"frame {r['frame']} on the fix grid recorded an older fix"
    assert on_grid >= len(rows) // 10 - 1  # one frame in ten falls on the grid (50 Hz / 5 Hz)


def test_gnss_position_recorded_is_near_the_truth(rows: list[dict[str, str]]) -> None:
    """A stale fix would sit one period (3 m at 15 m/s) behind: bounded by the noise instead."""
    errors = []
    for r in rows:
        dn = (float(r["gps_lat_deg"]) - float(r["lat_deg"])) * 111_320.0
        de = (
            (float(r["gps_lon_deg"]) - float(r["lon_deg"]))
            * 111_320.0
            * math.cos(math.radians(HOME.lat_deg))
        )
        errors.append(math.hypot(dn, de))
    errors.sort()
    assert errors[len(errors) // 2] < 5.0
