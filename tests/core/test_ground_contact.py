"""Ground contact: skimming the ground or flying into it is ``crashed`` (where, when, why) and
never a completed mission; a NAV_LAND touchdown within limits is ``landed``. Real JSBSim
flights through the fly command's recording path, summary.json read back."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import short_plans

from air_sitl.cli import main
from air_sitl.frames import ned2geodetic
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.68, lon_deg=25.28, alt_amsl_m=120.0)


def _plan(tmp_path: Path, items: list[tuple[int, float, float, float]]) -> Path:
    """(command, north m, east m, altitude above home m) items as a QGC plan."""
    placed = []
    for cmd, n, e, alt in items:
        lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
        placed.append((cmd, 3, lat, lon, alt))
    return short_plans.write_items_plan(tmp_path / "contact.plan", HOME, placed)


def _fly(tmp_path: Path, plan: Path) -> tuple[int, dict]:  # type: ignore[type-arg]
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--no-camera", "--air-start", "--out", str(out), "--quiet",
                 "--max-sim-time", "600", "--sensor-noise", "0"])  # fmt: skip
    return code, json.loads((out / "summary.json").read_text())


def test_a_waypoint_at_ground_level_is_a_crash_not_a_completed_mission(tmp_path: Path) -> None:
    plan = _plan(
        tmp_path,
        [(22, 0, 0, 40), (16, 0, 0, 40), (16, 600, 0, 40), (16, 1400, 0, 0), (16, 2000, 0, 40)],
    )
    code, s = _fly(tmp_path, plan)
    assert code == 1
    assert s["mission_completed"] is False and s["landed"] is False
    crash = s["crashed"]
    assert crash is not None and "outside a landing" in crash["reason"]
    # Where: on the leg down to the ground-level waypoint (north of the 600 m waypoint).
    north = (crash["lat_deg"] - HOME.lat_deg) * 111_320.0
    assert 600.0 < north < 1500.0
    assert abs(crash["lon_deg"] - HOME.lon_deg) < 0.001
    assert 0.0 < crash["sim_time_s"] < s["sim_time_s"] + 1e-9


def test_a_nav_land_touchdown_is_landed(tmp_path: Path) -> None:
    plan = _plan(tmp_path, [(22, 0, 0, 40), (16, 0, 0, 40), (16, 0, -600, 40), (21, 0, 300, 0)])
    code, s = _fly(tmp_path, plan)
    assert s["crashed"] is None, s["crashed"]
    assert s["landed"] is True and s["mission_completed"] is True and code == 0
