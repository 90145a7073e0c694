"""The Autopilot facade driven like a ground station would drive it (real JSBSim, on the ground
and just after take-off): arming, modes, refusals, status and events."""

from __future__ import annotations

import math
import re

import pytest

from air_sitl.autopilot.autopilot import Autopilot
from air_sitl.autopilot.control import Controller, gains_for
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.target import ControlPhase
from air_sitl.errors import PlanError
from air_sitl.fdm.base import InitialCondition, Wind
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.state import AutopilotStatus, FlightMode, VehicleState

from .sim import HOME, do, mission, rtl, wp

pytestmark = pytest.mark.integration


class Vehicle:
    """JSBSim + autopilot, stepped by the test."""

    def __init__(self, m: Mission, **kw: bool) -> None:
        self.fdm = JSBSimModel("airsitl_uav")
        initial = InitialCondition(
            lat_deg=HOME.lat_deg, lon_deg=HOME.lon_deg, alt_amsl_m=HOME.alt_amsl_m,
            heading_rad=0.0,
        )  # fmt: skip
        self.state = self.fdm.reset(HOME, initial, Wind())
        self.ap = Autopilot(m, HOME, ParamStore(), Controller(gains_for("airsitl_uav")), **kw)
        self.status: AutopilotStatus | None = None

    def run(self, seconds: float) -> VehicleState:
        end = self.state.sim_time_ns + int(seconds * 1e9)
        while self.state.sim_time_ns < end:
            command, self.status = self.ap.update(self.state)
            self.state = self.fdm.step(command)
        return self.state


def _mission() -> Mission:
    return mission(
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=16.0),
        wp(800, 0, 50),
        rtl(),
    )


def test_ground_station_flow_set_mode_then_arm() -> None:
    v = Vehicle(_mission(), auto_start=False)
    v.run(2.0)
    assert v.status is not None
    assert v.status.mode is FlightMode.IDLE and not v.status.armed
    assert v.ap.last_target.phase is ControlPhase.IDLE
    assert v.state.on_ground and v.state.airspeed_m_s < 0.5  # waits with brakes on
    assert v.ap.set_mode(FlightMode.MISSION) == (True, "")
    v.run(1.0)
    assert v.state.on_ground and v.status.mode is FlightMode.MISSION and not v.status.armed
    assert v.ap.arm() == (True, "")
    state = v.run(25.0)
    assert not state.on_ground and state.alt_agl_m > 20.0
    assert v.ap.disarm() == (False, "in the air")
    assert v.ap.arm() == (True, "already armed")
    assert v.ap.current_seq == 2 and v.ap.armed and v.ap.mode is FlightMode.MISSION
    assert v.ap.last_target.airspeed_m_s == 16.0  # DO_CHANGE_SPEED ran
    assert v.ap.pop_reached() == [0]
    events = v.ap.pop_events()
    assert events[:4] == ["Mode: MISSION", "Armed", "Mission started", "Takeoff to 40 m"]
    assert "Speed set to 16 m/s (air)" in events


def test_commands_on_the_ground_are_checked() -> None:
    v = Vehicle(_mission(), auto_start=False)
    v.run(0.5)
    assert v.ap.return_to_launch() == (False, "on the ground")
    assert v.ap.set_mode(FlightMode.LOITER) == (False, "on the ground")
    assert v.ap.reposition(HOME.lat_deg, HOME.lon_deg, math.nan) == (False, "on the ground")
    assert v.ap.disarm() == (True, "already disarmed")
    v.ap.set_mission(mission())  # clearing is allowed
    assert v.ap.set_mode(FlightMode.MISSION) == (False, "no mission")
    assert v.ap.current_seq == -1


def test_takeoff_command_climbs_then_loiters() -> None:
    v = Vehicle(_mission(), auto_start=False)
    v.run(0.5)
    assert v.ap.arm() == (True, "")
    assert v.ap.takeoff(30.0) == (True, "")
    state = v.run(60.0)
    assert v.ap.mode is FlightMode.LOITER
    assert state.alt_agl_m == pytest.approx(30.0, abs=5.0)
    assert v.ap.set_mode(FlightMode.RTL) == (True, "")
    assert v.ap.mode is FlightMode.RTL
    assert v.ap.change_speed(18.0) == (True, "")
    v.run(5.0)
    assert v.ap.last_target.airspeed_m_s == 18.0


def test_auto_start_and_air_start_flags() -> None:
    v = Vehicle(_mission())
    v.run(0.1)
    assert v.ap.armed and v.ap.mode is FlightMode.MISSION
    with pytest.raises(PlanError, match="no waypoint"):
        Vehicle(mission(wp(0, 0, 40, MavCmd.NAV_TAKEOFF), rtl()), air_start=True)


def test_commands_before_the_first_update_take_effect() -> None:
    """The runner's inbox may deliver a ground station's commands before the first step."""
    v = Vehicle(_mission(), auto_start=False)
    assert v.ap.set_mode(FlightMode.MISSION) == (True, "")
    assert v.ap.arm() == (True, "")
    state = v.run(20.0)
    assert not state.on_ground and v.ap.mode is FlightMode.MISSION


def test_a_mission_planned_for_another_place_is_refused_on_the_ground() -> None:
    # The vehicle at HOME, a plan about 500 km north: starting it would fly for hours.
    far = mission(wp(500_000, 0, 40, MavCmd.NAV_TAKEOFF), wp(501_000, 0, 50), rtl())
    v = Vehicle(far, auto_start=False)
    v.run(0.5)
    ok, reason = v.ap.set_mode(FlightMode.MISSION)  # QGC's DO_SET_MODE to MISSION
    assert not ok
    assert re.fullmatch(r"first waypoint is 49\d km from home \(limit 100 km\): .*", reason)
    assert v.ap.start_mission()[0] is False  # MAVSDK's MISSION_START
    v.run(0.5)
    assert v.ap.mode is FlightMode.IDLE and v.state.on_ground
    v.ap.set_mission(_mission())  # a plan near home flies
    assert v.ap.set_mode(FlightMode.MISSION) == (True, "")
    assert v.ap.arm() == (True, "")
