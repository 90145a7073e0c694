"""The autopilot flying the real JSBSim airsitl_uav with the real controller.

Each flight is short (a few seconds of CPU); the 12 AIR scenarios are flown by the lead's
script. Loop as the runner does: command, status = autopilot.update(state); state = step.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import pytest

from air_sitl.autopilot.autopilot import Autopilot, air_start_pose
from air_sitl.autopilot.control import Controller, gains_for
from air_sitl.autopilot.params import ParamStore
from air_sitl.fdm.base import InitialCondition, Wind
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.frames import geodetic2ned
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.state import AutopilotStatus, FlightMode, VehicleState

from .sim import HOME, do, mission, rtl, wp

pytestmark = pytest.mark.integration


@dataclass
class Flown:
    """What a test flight recorded."""

    autopilot: Autopilot
    state: VehicleState
    status: AutopilotStatus
    max_cross_track_m: float = 0.0
    max_alt_error_m: float = 0.0
    reached: list[int] = field(default_factory=list)
    events: list[str] = field(default_factory=list)
    capture_path: list[tuple[float, float]] = field(default_factory=list)
    phases: list[str] = field(default_factory=list)


def fly(m: Mission, *, air_start: bool, wind: Wind | None = None, max_s: float = 900.0) -> Flown:
    fdm = JSBSimModel("airsitl_uav")
    if air_start:
        lat, lon, alt, heading, speed = air_start_pose(m, HOME)
        initial = InitialCondition(
            lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, heading_rad=heading,
            airspeed_m_s=speed, on_ground=False,
        )  # fmt: skip
    else:
        initial = InitialCondition(
            lat_deg=HOME.lat_deg, lon_deg=HOME.lon_deg, alt_amsl_m=HOME.alt_amsl_m,
            heading_rad=0.0,
        )  # fmt: skip
    state = fdm.reset(HOME, initial, wind or Wind())
    controller = Controller(gains_for("airsitl_uav"), trim=fdm.trim_command)
    ap = Autopilot(m, HOME, ParamStore(), controller, air_start=air_start)
    out: Flown | None = None
    while state.sim_time_ns < max_s * 1e9:
        command, status = ap.update(state)
        if out is None:
            out = Flown(ap, state, status)
        out.state, out.status = state, status
        if status.reached_seq >= 0:
            out.reached.append(status.reached_seq)
        out.events.extend(ap.pop_events())
        phase = ap.last_target.phase.name
        if not out.phases or out.phases[-1] != phase:
            out.phases.append(phase)
        if status.tracking_settled:
            out.max_cross_track_m = max(out.max_cross_track_m, abs(status.cross_track_m))
            out.max_alt_error_m = max(out.max_alt_error_m, abs(status.alt_error_m))
        if status.capturing and state.sim_time_ns % 20_000_000 == 0:
            out.capture_path.append((state.pos_ned_m[0], state.pos_ned_m[1]))
        if status.mission_completed:
            break
        state = fdm.step(command)
    assert out is not None
    return out


def _length(path: list[tuple[float, float]]) -> float:
    return sum(math.dist(a, b) for a, b in itertools.pairwise(path))


def test_mission_from_the_ground_takes_off_flies_and_returns() -> None:
    m = mission(
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        wp(400, 0, 60),
        wp(400, 400, 60),
        wp(0, 400, 60),
        rtl(),
    )
    f = fly(m, air_start=False)
    assert f.status.mission_completed and f.status.mode is FlightMode.RTL
    assert f.reached == [0, 1, 2, 3, 4]
    assert f.phases[:3] == ["GROUND_ROLL", "CLIMB", "CRUISE"]  # auto start: armed at once
    assert f.events[:3] == ["Mode: MISSION", "Armed", "Mission started"]
    assert "Takeoff complete" in f.events and "Mission finished" in f.events
    assert f.max_cross_track_m <= 15.0 and f.max_alt_error_m <= 10.0
    assert math.hypot(*f.state.pos_ned_m[:2]) == pytest.approx(80.0, abs=10.0)  # home loiter
    # Without camera items the capture window ends with the mission.
    assert not f.status.capturing and "Capture started" in f.events


@pytest.mark.parametrize("wind", [None, Wind(speed_m_s=6.0, from_deg=90.0)], ids=["calm", "side"])
def test_square_air_start_tracks_the_legs(wind: Wind | None) -> None:
    m = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(300, 0, 100),
        do(MavCmd.IMAGE_START_CAPTURE, param2=0.02),
        wp(900, 0, 100), wp(900, 600, 100), wp(300, 600, 100), wp(300, 0, 100),
        do(MavCmd.IMAGE_STOP_CAPTURE),
    )  # fmt: skip
    f = fly(m, air_start=True, wind=wind)
    assert f.status.mission_completed
    assert f.reached == [0, 1, 3, 4, 5, 6]
    assert f.max_cross_track_m <= 15.0, f.max_cross_track_m
    assert f.max_alt_error_m <= 10.0, f.max_alt_error_m
    # Corners are cut by the turn anticipation: a little under the 2400 m drawn.
    assert 2300.0 < _length(f.capture_path) <= 2400.0
    assert math.dist(f.capture_path[-1], (300.0, 0.0)) < 30.0  # loop closed


def test_circle_air_start_keeps_its_radius_and_closes() -> None:
    radius = 150.0
    m = mission(
        wp(0, 0, 50, MavCmd.NAV_TAKEOFF),
        wp(400, -400, 120),
        wp(400, 0, 120),  # S, on the circle; the run-in is its tangent
        do(MavCmd.IMAGE_START_CAPTURE, param2=0.02),
        wp(400 - radius, 0, 120, MavCmd.NAV_LOITER_TURNS, param1=1.0, param3=radius),
        do(MavCmd.IMAGE_STOP_CAPTURE),
        rtl(),
    )
    f = fly(m, air_start=True, wind=Wind(speed_m_s=5.0, from_deg=0.0))
    assert f.status.mission_completed
    radii = [math.hypot(n - (400.0 - radius), e) for n, e in f.capture_path]
    assert max(abs(r - radius) for r in radii) <= 0.1 * radius
    assert _length(f.capture_path) == pytest.approx(2 * math.pi * radius, rel=0.05)
    assert math.dist(f.capture_path[-1], (400.0, 0.0)) < 25.0
    assert f.max_cross_track_m <= 15.0 and f.max_alt_error_m <= 10.0


def test_land_item_glides_down_and_disarms() -> None:
    m = mission(
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        wp(0, 0, 40),
        wp(0, -600, 40),
        wp(0, 0, 0, MavCmd.NAV_LAND),
    )
    f = fly(m, air_start=True)
    assert f.status.mission_completed and not f.status.armed
    assert f.status.mode is FlightMode.IDLE and f.state.on_ground
    assert "Landed" in f.events and "Disarmed" in f.events
    n, e, _ = f.state.pos_ned_m
    assert abs(n) < 10.0 and -100.0 < e < 250.0  # on the runway line, near the touchdown point


def test_air_start_pose_matches_the_first_waypoint() -> None:
    m = mission(wp(0, 0, 50, MavCmd.NAV_TAKEOFF), wp(300, 200, 100), wp(300, 900, 100))
    lat, lon, alt, heading, speed = air_start_pose(m, HOME)
    n, e, _ = geodetic2ned(lat, lon, alt, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    assert (n, e) == pytest.approx((300.0, 200.0), abs=0.01)
    assert heading == pytest.approx(math.pi / 2, abs=1e-6) and speed == 15.0
