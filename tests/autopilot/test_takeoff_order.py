"""A mission with a navigation item before its NAV_TAKEOFF: PX4 accepts the upload, then its
feasibility check refuses to start it ("Mission rejected: takeoff not first waypoint item"; DO
items and NAV_DELAY before the take-off do not count). The executor refuses the start with that
reason (serve answers DENIED + STATUSTEXT); ``fly`` refuses the plan with it."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.params import ParamStore
from air_sitl.cli import main
from air_sitl.mission.items import MavCmd
from air_sitl.mission.validate import TAKEOFF_NOT_FIRST, takeoff_order_problem
from air_sitl.state import FlightMode

from .sim import HOME, KinematicPlane, do, mission, run, wp

PX4_TEXT = "Mission rejected: takeoff not first waypoint item"  # PX4's STATUSTEXT, verbatim


def _waypoint_first() -> tuple:  # type: ignore[type-arg]
    return (wp(300, 0, 50), wp(0, 0, 40, MavCmd.NAV_TAKEOFF), wp(600, 0, 50))


def test_px4_text() -> None:
    assert TAKEOFF_NOT_FIRST == PX4_TEXT


def test_start_is_refused_with_px4s_reason() -> None:
    ex = MissionExecutor(mission(*_waypoint_first()), HOME, ParamStore())
    plane = KinematicPlane()
    ex.update(plane.state())
    ok, reason = ex.set_mode(FlightMode.MISSION)
    assert not ok and reason.startswith(PX4_TEXT)
    assert "item 0 NAV_WAYPOINT before NAV_TAKEOFF at item 1" in reason
    assert ex.mode is FlightMode.IDLE
    ok, _ = ex.start_mission()
    assert not ok
    # Arming works (not in MISSION mode), nothing flies.
    assert ex.arm()[0]
    state = run(ex, plane, until=lambda _x, _s: False, max_s=20)
    assert state.on_ground and ex.current_seq <= 0


def test_do_items_and_delay_before_the_takeoff_do_not_count() -> None:
    items = (
        do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=16.0),
        do(MavCmd.NAV_DELAY, param1=2.0),
        do(MavCmd.IMAGE_START_CAPTURE, param2=0.02),
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        wp(600, 0, 40),
    )
    assert takeoff_order_problem(items) == ""
    ex = MissionExecutor(mission(*items), HOME, ParamStore())
    plane = KinematicPlane()
    ex.update(plane.state())
    assert ex.set_mode(FlightMode.MISSION) == (True, "")
    assert ex.arm()[0]
    run(ex, plane)
    assert ex.mission_completed


def test_without_a_takeoff_item_any_order_is_fine() -> None:
    assert takeoff_order_problem((wp(300, 0, 50), wp(600, 0, 50))) == ""


def test_fly_refuses_the_plan_with_the_same_reason(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def item(cmd: int, n: float, alt: float) -> dict[str, object]:
        lat = HOME.lat_deg + n / 111_320.0
        return {"type": "SimpleItem", "command": cmd, "frame": 3, "autoContinue": True,
                "params": [0, 0, 0, None, lat, HOME.lon_deg, alt]}  # fmt: skip

    doc = {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"version": 2, "firmwareType": 12, "vehicleType": 1, "cruiseSpeed": 15,
                    "plannedHomePosition": [HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m],
                    "items": [item(16, 300, 50), item(22, 0, 40), item(16, 600, 50)]},
    }  # fmt: skip
    plan = tmp_path / "order.plan"
    plan.write_text(json.dumps(doc))
    code = main(["fly", str(plan), "--no-camera", "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code != 0, err  # a known error: one line, no traceback
    assert PX4_TEXT in err and "order.plan" in err
    assert not (tmp_path / "out" / "summary.json").exists()
