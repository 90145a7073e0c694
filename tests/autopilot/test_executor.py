"""Mission state machine on a kinematic aircraft: sequencing, DO_JUMP, capture, loiters, modes."""

from __future__ import annotations

import itertools
import math

import pytest

from air_sitl.autopilot.autopilot import air_start_pose
from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.target import ControlPhase
from air_sitl.autopilot.tasks import LoiterTask, NavOutput
from air_sitl.errors import PlanError
from air_sitl.mission.items import MavCmd
from air_sitl.state import FlightMode, VehicleState

from .sim import HOME, KinematicPlane, air_started, do, ground_started, mission, rtl, run, wp


def _reached_log(ex: MissionExecutor, plane: KinematicPlane, **kw: float) -> list[int]:
    log: list[int] = []

    def each(x: MissionExecutor, _s: VehicleState, _o: NavOutput) -> None:
        log.extend(x.pop_reached())

    run(ex, plane, each=each, **kw)  # type: ignore[arg-type]
    log.extend(ex.pop_reached())
    return log


def test_square_is_flown_in_order_and_tracked() -> None:
    m = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(500, 0, 100), wp(500, 500, 100), wp(0, 500, 100), wp(0, 0, 100),
    )  # fmt: skip
    ex, plane = air_started(m)
    worst = [0.0, 0.0]

    def each(x: MissionExecutor, _s: VehicleState, out: NavOutput) -> None:
        if out.settled:
            worst[0] = max(worst[0], abs(out.cross_track_m))
            worst[1] = max(worst[1], abs(out.alt_error_m))

    state = run(ex, plane, each=each)
    assert ex.mission_completed
    assert worst[0] < 5.0 and worst[1] < 2.0
    assert ex.mode is FlightMode.LOITER  # PX4: loiter at the last waypoint
    assert math.hypot(state.pos_ned_m[0], state.pos_ned_m[1]) < 60.0


def test_take_off_from_the_ground_phases_and_runway_heading() -> None:
    m = mission(wp(0, 0, 40, MavCmd.NAV_TAKEOFF), wp(0, 600, 40), rtl())
    ex = MissionExecutor(m, HOME, ParamStore())
    plane = KinematicPlane()
    ex.update(plane.state())
    assert ex.set_mode(FlightMode.MISSION)[0]
    assert ex.mode is FlightMode.MISSION and not ex.armed
    assert ex.update(plane.state()).target.phase is ControlPhase.IDLE  # waits for arming
    assert ex.arm() == (True, "")
    phases: list[ControlPhase] = []
    headings: list[float] = []

    def each(_x: MissionExecutor, _s: VehicleState, out: NavOutput) -> None:
        if not phases or phases[-1] is not out.target.phase:
            phases.append(out.target.phase)
            headings.append(out.target.heading_rad)

    run(ex, plane, each=each, until=lambda x, _s: x.current_seq == 1)
    assert phases[:3] == [ControlPhase.GROUND_ROLL, ControlPhase.CLIMB, ControlPhase.CRUISE]
    assert headings[0] == pytest.approx(math.pi / 2)  # toward the first waypoint (east)
    assert plane.alt - HOME.alt_amsl_m > 30.0
    events = ex.pop_events()
    assert "Armed" in events and "Takeoff to 40 m" in events and "Takeoff complete" in events


def test_do_jump_repeats_like_px4() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 100),  # 1
        wp(300, 300, 100),  # 2
        do(MavCmd.DO_JUMP, param1=1, param2=2),  # 3: back to 1, twice
        wp(0, 300, 100),  # 4
    )
    ex, plane = air_started(mission(*items))
    log = _reached_log(ex, plane)
    assert log == [0, 1, 2, 1, 2, 1, 2, 4]
    assert ex.mission_completed


def test_nested_do_jumps_keep_their_counters_like_px4() -> None:
    """PX4 does not reset an inner jump's counter when an outer jump repeats the loop."""
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 100),  # 1
        wp(300, 300, 100),  # 2
        do(MavCmd.DO_JUMP, param1=1, param2=1),  # 3: inner
        wp(0, 300, 100),  # 4
        do(MavCmd.DO_JUMP, param1=1, param2=1),  # 5: outer
    )
    ex, plane = air_started(mission(*items))
    assert _reached_log(ex, plane) == [0, 1, 2, 1, 2, 4, 1, 2, 4]
    assert ex.mode is FlightMode.LOITER


def test_do_jump_with_zero_repeats_never_jumps() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 100),
        wp(300, 300, 100),
        do(MavCmd.DO_JUMP, param1=1, param2=0),
        wp(0, 300, 100),
    )
    ex, plane = air_started(mission(*items))
    assert _reached_log(ex, plane) == [0, 1, 2, 4]


def test_capture_window_follows_start_and_stop_items() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 100),  # 1: start point of the air start
        wp(600, 0, 100),  # 2
        do(MavCmd.IMAGE_START_CAPTURE, param2=0.02),  # 3
        wp(900, 0, 100),  # 4
        do(MavCmd.IMAGE_STOP_CAPTURE),  # 5
        wp(1200, 0, 100),  # 6
    )
    ex, plane = air_started(mission(*items))
    at_seq: dict[int, set[bool]] = {}

    def each(x: MissionExecutor, _s: VehicleState, _o: NavOutput) -> None:
        at_seq.setdefault(x.current_seq, set()).add(x.capturing)

    run(ex, plane, each=each)
    assert at_seq[2] == {False} and at_seq[4] == {True} and at_seq[6] == {False}
    events = ex.pop_events()
    assert events.count("Capture started") == 1 and events.count("Capture stopped") == 1


def test_default_capture_window_starts_at_first_waypoint_at_altitude() -> None:
    """No camera items: from the first waypoint after take-off (at its altitude) to the end."""
    items = (wp(0, 0, 40, MavCmd.NAV_TAKEOFF), wp(0, 800, 120), wp(0, 1600, 120))
    ex, plane = ground_started(mission(*items))
    first: list[tuple[int, float, float]] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        if x.capturing and not first:
            first.append((x.current_seq, s.pos_ned_m[1], s.alt_agl_m))

    run(ex, plane, each=each)
    seq, east, height = first[0]
    assert seq == 2 and east > 700.0 and abs(height - 120.0) <= 10.0
    assert ex.mission_completed and not ex.capturing


def test_default_capture_waits_for_the_altitude() -> None:
    # The first waypoint is reached long before the aircraft climbs to its altitude.
    items = (wp(0, 0, 40, MavCmd.NAV_TAKEOFF), wp(0, 200, 300), wp(0, 3000, 300))
    ex, plane = ground_started(mission(*items))
    start: list[float] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        if x.capturing and not start:
            start.append(s.alt_agl_m)

    run(ex, plane, each=each)
    assert start and start[0] >= 290.0


def test_missed_acceptance_radius_switches_at_the_perpendicular() -> None:
    """A 1 m acceptance radius that the aircraft misses never makes it circle back."""
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 100),
        wp(0, 250, 100, param2=1.0),  # 2: tiny acceptance radius
        wp(0, 2000, 100),
    )
    # A strong crosswind and a short leg: the aircraft passes the waypoint off to the side.
    ex, plane = air_started(mission(*items), wind_ne=(7.0, 0.0))
    plane.n = -60.0
    worst_turn = [0.0]
    switched: list[float] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        worst_turn[0] = max(worst_turn[0], abs(s.yaw_rad - math.pi / 2))
        if x.current_seq == 3 and not switched:
            switched.append(s.pos_ned_m[1])

    run(ex, plane, each=each, until=lambda x, s: s.pos_ned_m[1] > 600.0)
    assert switched and 240.0 <= switched[0] <= 260.0
    assert worst_turn[0] < math.radians(80.0)  # never turned back


def _circle_mission(turns: float, radius: float) -> tuple[object, ...]:
    # Run-in east along n = 300 to S = (300, 0); centre (300 - r, 0) for clockwise flight.
    return (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, -500, 150),
        wp(300, 0, 150),  # S
        do(MavCmd.IMAGE_START_CAPTURE, param2=0.02),
        wp(300 - abs(radius), 0, 150, MavCmd.NAV_LOITER_TURNS, param1=turns, param3=radius),
        do(MavCmd.IMAGE_STOP_CAPTURE),
        rtl(),
    )


def test_one_loiter_turn_returns_to_the_start_point() -> None:
    ex, plane = air_started(mission(*_circle_mission(1.0, 160.0)))  # type: ignore[arg-type]
    path: list[tuple[float, float]] = []
    radii: list[float] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        if x.capturing:
            path.append((s.pos_ned_m[0], s.pos_ned_m[1]))
            radii.append(math.hypot(s.pos_ned_m[0] - 140.0, s.pos_ned_m[1]))

    run(ex, plane, each=each)
    length = sum(math.dist(a, b) for a, b in itertools.pairwise(path))
    assert length == pytest.approx(2 * math.pi * 160.0, rel=0.03)
    assert math.dist(path[-1], (300.0, 0.0)) < 20.0  # back at S
    assert max(abs(r - 160.0) for r in radii) < 5.0
    assert ex.mode is FlightMode.RTL and ex.mission_completed


def test_loiter_direction_follows_the_radius_sign() -> None:
    # Negative radius: counter-clockwise; S at the south point of a circle centred at (460, 0)?
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, -500, 150),
        wp(300, 0, 150),
        wp(460, 0, 150, MavCmd.NAV_LOITER_TURNS, param1=0.5, param3=-160.0),
    )
    ex, plane = air_started(mission(*items))
    run(ex, plane, until=lambda x, _s: x.current_seq == 3)
    task = ex.task
    assert isinstance(task, LoiterTask) and task.direction == -1
    state = run(ex, plane)
    # Half a turn counter-clockwise from the south point ends at the north point (620, 0).
    assert math.dist(state.pos_ned_m[:2], (620.0, 0.0)) < 25.0


def test_loiter_time_and_loiter_to_altitude() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 100),
        wp(0, 0, 100, MavCmd.NAV_LOITER_TIME, param1=60.0, param3=100.0),  # 2
        wp(0, 0, 160, MavCmd.NAV_LOITER_TO_ALT, param2=100.0),  # 3
        wp(0, 600, 160),  # 4
    )
    ex, plane = air_started(mission(*items))
    times: dict[int, float] = {}

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        times.setdefault(x.current_seq, s.sim_time_ns / 1e9)
        task = x.task
        if isinstance(task, LoiterTask) and task.established:
            times.setdefault(-x.current_seq, s.sim_time_ns / 1e9)

    state = run(ex, plane, each=each, until=lambda x, _s: x.current_seq == 4)
    assert times[3] - times[-2] == pytest.approx(60.0, abs=0.05)  # 60 s once on the circle
    assert abs(state.alt_agl_m - 160.0) <= 10.0


def test_do_change_speed_sets_the_airspeed_target() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 100),
        wp(0, 500, 100),
        do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=19.0, param3=-1.0),
        wp(0, 1000, 100),
    )
    ex, plane = air_started(mission(*items, speed=14.0))
    assert ex.update(plane.state()).target.airspeed_m_s == 14.0  # the plan's cruise speed
    speeds: set[float] = set()
    run(
        ex,
        plane,
        each=lambda x, _s, o: speeds.add(o.target.airspeed_m_s) if x.current_seq == 4 else None,
    )
    assert speeds == {19.0}


def test_rtl_climbs_to_return_altitude_and_loiters_at_home() -> None:
    items = (wp(0, 0, 30, MavCmd.NAV_TAKEOFF), wp(0, 0, 30), wp(800, 0, 30), rtl())
    ex, plane = air_started(mission(*items))
    state = run(ex, plane)
    assert ex.mode is FlightMode.RTL and ex.mission_completed
    assert math.hypot(*state.pos_ned_m[:2]) == pytest.approx(80.0, abs=10.0)  # NAV_LOITER_RAD
    assert state.alt_agl_m == pytest.approx(60.0, abs=10.0)  # RTL_RETURN_ALT


def test_loiter_unlimited_at_the_end_completes_the_mission_once_established() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 100),
        wp(0, 800, 100, MavCmd.NAV_LOITER_UNLIM),
    )
    ex, plane = air_started(mission(*items))
    state = run(ex, plane)
    assert ex.mission_completed and ex.mode is FlightMode.MISSION
    assert math.hypot(state.pos_ned_m[0], state.pos_ned_m[1] - 800.0) == pytest.approx(
        80.0, abs=10.5
    )


def test_land_item_touches_down_and_disarms() -> None:
    items = (
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 40),
        wp(0, -500, 40),
        wp(0, 0, 0, MavCmd.NAV_LAND),
    )
    ex, plane = air_started(mission(*items))
    state = run(ex, plane)
    assert ex.mission_completed and not ex.armed and ex.mode is FlightMode.IDLE
    assert state.on_ground
    assert abs(state.pos_ned_m[0]) < 10.0 and -150.0 < state.pos_ned_m[1] < 150.0


def test_commands_and_pre_arm_checks() -> None:
    items = (wp(0, 0, 50, MavCmd.NAV_TAKEOFF), wp(0, 0, 100), wp(0, 2000, 100))
    ex, plane = air_started(mission(*items))
    state = run(ex, plane, until=lambda _x, s: s.sim_time_ns > 5e9)
    assert ex.arm() == (True, "already armed")
    assert ex.disarm() == (False, "in the air")
    assert ex.takeoff(50.0)[0] is False
    assert ex.set_current(99)[0] is False
    assert ex.change_speed(17.0) == (True, "")
    assert ex.update(state).target.airspeed_m_s == 17.0
    assert ex.reposition(HOME.lat_deg, HOME.lon_deg, math.nan)[0]
    assert ex.mode is FlightMode.LOITER
    state = run(ex, plane, until=lambda _x, s: s.sim_time_ns > 150e9)
    assert math.hypot(*state.pos_ned_m[:2]) == pytest.approx(80.0, abs=8.0)
    assert ex.return_to_launch()[0] and ex.mode is FlightMode.RTL
    assert ex.set_current(2)[0] and ex.current_seq == 2
    assert ex.start_mission()[0] and ex.mode is FlightMode.MISSION
    events = ex.pop_events()
    assert "Mode: LOITER" in events and "Mode: RTL" in events and "Mode: MISSION" in events


def test_arm_is_refused_in_the_air_and_without_mission() -> None:
    ex = MissionExecutor(mission(), HOME, ParamStore())
    ex.update(KinematicPlane().state())
    assert ex.start_mission() == (False, "no mission")
    m = mission(wp(0, 0, 50, MavCmd.NAV_TAKEOFF), wp(0, 300, 100))
    ex = MissionExecutor(m, HOME, ParamStore())
    ex.update(KinematicPlane(alt_rel=100.0, airspeed=15.0).state())
    assert ex.arm() == (False, "not on the ground")


def test_set_mission_in_flight_restarts_the_new_mission() -> None:
    items = (wp(0, 0, 50, MavCmd.NAV_TAKEOFF), wp(0, 0, 100), wp(0, 2000, 100))
    ex, plane = air_started(mission(*items))
    run(ex, plane, until=lambda _x, s: s.sim_time_ns > 10e9)
    assert ex.pop_reached() == [0, 1]
    new = mission(wp(0, 0, 50, MavCmd.NAV_TAKEOFF), wp(-500, 300, 120), wp(-1000, 300, 120))
    ex.set_mission(new)
    log = _reached_log(ex, plane)
    assert log == [0, 1, 2] and ex.mission_completed


def test_air_start_pose() -> None:
    m = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        do(MavCmd.DO_CHANGE_SPEED, param1=1.0, param2=13.0),
        wp(300, 0, 200),
        wp(300, 400, 200),
    )
    lat, lon, alt, heading, speed = air_start_pose(m, HOME)
    first = m.items[2]
    assert (lat, lon) == pytest.approx((first.lat_deg, first.lon_deg), abs=1e-7)
    assert alt == HOME.alt_amsl_m + 200.0
    assert heading == pytest.approx(math.pi / 2, abs=1e-3)
    assert speed == 13.0
    # The AIR circle layout: heading along the circle's tangent at S when S is the first point.
    c = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 200),
        wp(140, 0, 200, MavCmd.NAV_LOITER_TURNS, param1=1.0, param3=-160.0),
    )
    assert air_start_pose(c, HOME)[3] == pytest.approx(-math.pi / 2, abs=1e-3)
    with pytest.raises(PlanError):
        air_start_pose(mission(wp(0, 0, 50, MavCmd.NAV_TAKEOFF), rtl()), HOME)


def test_ground_speed_change_is_flown_against_the_wind() -> None:
    items = (
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        do(MavCmd.DO_CHANGE_SPEED, param1=1.0, param2=13.0),  # ground speed
        wp(0, 0, 100),
        wp(3000, 0, 100),
    )
    ex, plane = air_started(mission(*items), wind_ne=(-5.0, 0.0))  # 5 m/s headwind
    state = run(ex, plane, until=lambda _x, s: s.sim_time_ns > 60e9)
    assert ex.update(state).target.airspeed_m_s == pytest.approx(18.0, abs=0.1)
    assert state.vel_ned_m_s[0] == pytest.approx(13.0, abs=0.1)
