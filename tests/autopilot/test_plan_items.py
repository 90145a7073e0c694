"""Standard mission items beyond waypoints: what PX4 does with each, and what we do.

Flown: NAV_DELAY (hold), NAV_SPLINE_WAYPOINT (as a waypoint), DO_LAND_START (RTL flies the
mission landing, as PX4 fixed wings do), DO_SET_CAM_TRIGG_DIST and DO_DIGICAM_CONTROL (capture
window). Skipped with one warning per item: DO_MOUNT_CONTROL, DO_GRIPPER, DO_PARACHUTE,
SET_CAMERA_MODE. Refused by name: NAV_VTOL_TAKEOFF.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.tasks import NavOutput
from air_sitl.errors import PlanError
from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd
from air_sitl.mission.plan_file import load_mission
from air_sitl.mission.validate import mission_warnings
from air_sitl.state import FlightMode, VehicleState

from .sim import HOME, KinematicPlane, air_started, do, mission, run, wp


def _ll(n: float, e: float) -> tuple[float, float]:
    lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    return lat, lon


def _simple(command: int, params: list[Any], frame: int = 3) -> dict[str, Any]:
    return {"type": "SimpleItem", "command": command, "frame": frame, "autoContinue": True,
            "params": params}  # fmt: skip


def _plan(items: list[dict[str, Any]], vehicle_type: int = 1) -> dict[str, Any]:
    for k, item in enumerate(items, start=1):
        item.setdefault("doJumpId", k)
    return {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "geoFence": {"circles": [], "polygons": [], "version": 2},
        "rallyPoints": {"points": [], "version": 2},
        "mission": {
            "version": 2, "firmwareType": 12, "vehicleType": vehicle_type, "cruiseSpeed": 15,
            "hoverSpeed": 5, "items": items,
            "plannedHomePosition": [HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m],
        },
    }  # fmt: skip


def _write(tmp_path: Path, doc: dict[str, Any], name: str = "items.plan") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc, indent=4))
    return path


def test_payload_items_are_skipped_with_one_warning_each(tmp_path: Path) -> None:
    a, b = _ll(0, 0), _ll(800, 0)
    doc = _plan(
        [
            _simple(22, [15, 0, 0, None, *a, 40]),
            _simple(530, [0, 0, None, None, None, None, None], 2),  # SET_CAMERA_MODE photo
            _simple(205, [-45, 0, 0, None, None, None, 2], 2),  # DO_MOUNT_CONTROL pitch
            _simple(16, [0, 0, 0, None, *b, 40]),
            _simple(211, [1, 0, None, None, None, None, None], 2),  # DO_GRIPPER release
            _simple(208, [2, None, None, None, None, None, None], 2),  # DO_PARACHUTE release
            _simple(20, [0, 0, 0, 0, 0, 0, 0], 2),
        ]
    )
    m = load_mission(_write(tmp_path, doc))
    warnings = mission_warnings(m)
    assert len(warnings) == 4
    for index, name in ((1, "SET_CAMERA_MODE"), (2, "DO_MOUNT_CONTROL"), (4, "DO_GRIPPER"),
                        (5, "DO_PARACHUTE")):  # fmt: skip
        (line,) = [w for w in warnings if w.startswith(f"item {index}: ")]
        assert f"{name} skipped: " in line and len(line.split("skipped: ")[1]) > 10
    # The executor says so too (STATUSTEXT on serve), once per item, and flies the rest.
    ex, plane = air_started(m)
    assert sum("skipped" in e for e in ex.pop_events()) == 4
    run(ex, plane)
    assert ex.mission_completed and ex.mode is FlightMode.RTL


def test_vtol_takeoff_is_refused_by_its_name(tmp_path: Path) -> None:
    doc = _plan([_simple(84, [0, 0, 0, None, *_ll(0, 0), 40]), _simple(16, [0, 0, 0, None,
                 *_ll(500, 0), 40])])  # fmt: skip
    with pytest.raises(PlanError, match=r"item 0: NAV_VTOL_TAKEOFF cannot be flown: .*vertic"):
        load_mission(_write(tmp_path, doc))


def test_unknown_commands_still_name_their_number(tmp_path: Path) -> None:
    doc = _plan([_simple(16, [0, 0, 0, None, *_ll(0, 0), 40]), _simple(31010, [0] * 7, 2)])
    with pytest.raises(PlanError, match=r"item 1: unknown command.*\(31010\)"):
        load_mission(_write(tmp_path, doc))


def test_spline_waypoint_is_flown_as_a_waypoint(tmp_path: Path) -> None:
    doc = _plan(
        [
            _simple(22, [15, 0, 0, None, *_ll(0, 0), 40]),
            _simple(16, [0, 0, 0, None, *_ll(0, 0), 40]),
            _simple(82, [0, 0, 0, None, *_ll(600, 300), 40]),
            _simple(16, [0, 0, 0, None, *_ll(600, 900), 40]),
        ]
    )
    m = load_mission(_write(tmp_path, doc))
    assert mission_warnings(m) == [
        "item 2: NAV_SPLINE_WAYPOINT flown as a waypoint (straight legs, no spline)"
    ]
    ex, plane = air_started(m)
    passes: list[float] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        passes.append(math.hypot(s.pos_ned_m[0] - 600.0, s.pos_ned_m[1] - 300.0))

    reached: list[int] = []
    run(ex, plane, each=lambda x, s, o: (each(x, s, o), reached.extend(x.pop_reached())))
    assert 2 in reached and ex.mission_completed
    assert min(passes) < 60.0  # it went to the spline point


def test_nav_delay_holds_for_its_seconds_then_goes_on() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 50),
        wp(600, 0, 50),
        do(MavCmd.NAV_DELAY, param1=40.0),
        wp(600, 800, 50),
    )
    ex, plane = air_started(mission(*items))
    times: dict[int, float] = {}

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        for seq in x.pop_reached():
            times.setdefault(seq, s.sim_time_ns / 1e9)

    state = run(ex, plane, each=each)
    assert ex.mission_completed
    # The delay ends 40 s (one guidance step) after waypoint 2 was reached, not at once.
    assert times[3] - times[2] == pytest.approx(40.0, abs=0.05)
    assert math.hypot(state.pos_ned_m[0] - 600.0, state.pos_ned_m[1] - 800.0) < 100.0


def test_rtl_flies_the_mission_landing_from_do_land_start() -> None:
    """PX4 fixed wing (RTL_TYPE default): return to the start of the mission landing pattern
    and land on it, not at home. QGC's landing pattern uploads DO_LAND_START, a
    NAV_LOITER_TO_ALT approach point and NAV_LAND."""
    lat, lon = _ll(-1500.0, 1500.0)
    items = (
        wp(0, 0, 60, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 60),
        wp(3000, 0, 60),
        wp(3000, 3000, 60),
        do(MavCmd.DO_LAND_START, lat_deg=lat, lon_deg=lon),
        wp(-1500, 1500, 40, MavCmd.NAV_LOITER_TO_ALT),
        wp(-1500, 2200, 0, MavCmd.NAV_LAND),
    )
    ex, plane = air_started(mission(*items))
    # Fly to the far corner, then RTL from there (as a ground station would command it).
    state = run(ex, plane, until=lambda x, _s: x.current_seq == 3)
    ok, reason = ex.return_to_launch()
    assert ok, reason
    assert ex.mode is FlightMode.RTL and ex.current_seq == 5
    state = run(ex, plane, until=lambda x, s: s.on_ground and not x.armed, max_s=3000)
    assert state.on_ground and not ex.armed
    # On the landing line, near its touchdown point, far from home.
    assert abs(state.pos_ned_m[0] + 1500.0) < 20.0
    assert 1800.0 < state.pos_ned_m[1] < 2500.0
    assert ex.mission_completed


def test_rtl_without_a_landing_sequence_still_goes_home() -> None:
    items = (wp(0, 0, 60, MavCmd.NAV_TAKEOFF), wp(0, 0, 60), wp(1000, 0, 60))
    ex, plane = air_started(mission(*items))
    run(ex, plane, until=lambda x, _s: x.current_seq == 2)
    assert ex.return_to_launch()[0]
    state = run(ex, plane, until=lambda _x, _s: False, max_s=plane.t_ns / 1e9 + 300)
    assert math.hypot(*state.pos_ned_m[:2]) < 120.0


def _capture_log(m_items: tuple[Any, ...]) -> tuple[MissionExecutor, list[tuple[float, bool]]]:
    ex, plane = air_started(mission(*m_items))
    log: list[tuple[float, bool]] = []
    run(ex, plane, each=lambda x, s, _o: log.append((s.pos_ned_m[0], x.capturing)))
    return ex, log


def test_camera_trigger_distance_opens_and_closes_the_capture_window() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 50),
        wp(300, 0, 50),
        do(MavCmd.DO_SET_CAM_TRIGG_DIST, param1=25.0),
        wp(900, 0, 50),
        do(MavCmd.DO_SET_CAM_TRIGG_DIST, param1=0.0),
        wp(1200, 0, 50),
    )
    ex, log = _capture_log(items)
    captured = [n for n, c in log if c]
    assert ex.mission_completed and captured
    # Open from waypoint 2 to waypoint 4 (within the acceptance/turn switch distance).
    assert min(captured) == pytest.approx(300.0, abs=40.0)
    assert max(captured) == pytest.approx(900.0, abs=40.0)
    assert not log[-1][1]


def test_digicam_shot_captures_one_frame() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 50),
        wp(400, 0, 50),
        do(MavCmd.DO_DIGICAM_CONTROL, lat_deg=1.0),  # param5 = 1: shoot
        wp(900, 0, 50),
    )
    ex, log = _capture_log(items)
    assert ex.mission_completed
    assert sum(c for _, c in log) == 1  # one guidance step = one 50 Hz camera frame


def test_a_plan_with_a_capture_item_has_no_default_window() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 50),
        wp(600, 0, 50),
        do(MavCmd.DO_SET_CAM_TRIGG_DIST, param1=0.0),
    )
    ex = MissionExecutor(mission(*items), HOME, ParamStore())
    plane = KinematicPlane()
    ex.set_mode(FlightMode.MISSION)
    ex.arm()
    log: list[bool] = []
    run(ex, plane, each=lambda x, _s, _o: log.append(x.capturing))
    assert ex.mission_completed and not any(log)


def test_loiter_unlimited_before_other_items_says_the_flight_ends_at_the_time_limit() -> None:
    """PX4: NAV_LOITER_UNLIM never ends; what follows it is never flown. Said at the start."""
    m = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(600, 0, 50, MavCmd.NAV_LOITER_UNLIM),
        wp(1200, 0, 50),
    )
    (warning,) = mission_warnings(m)
    assert warning.startswith("item 1: NAV_LOITER_UNLIM never ends")
    assert "--max-sim-time" in warning
    ex, plane = air_started(m)
    run(ex, plane, until=lambda _x, _s: False, max_s=600)
    assert not ex.mission_completed and ex.current_seq == 1
    # As the last item it completes the mission once established (no warning).
    assert mission_warnings(mission(*m.items[:2])) == []
