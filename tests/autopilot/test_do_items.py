"""DO items on their own: jump counters, the speed asked for (air or ground), capture items."""

from __future__ import annotations

import math

import pytest

from air_sitl.autopilot.do_items import DoItems
from air_sitl.autopilot.params import GuidanceParams, ParamStore
from air_sitl.mission.items import MavCmd, MissionItem

from .sim import KinematicPlane, do, wp


class _Sequencer:
    """What the sequencer sees of its DO items: the events in order and the capture window."""

    def __init__(self) -> None:
        self.events: list[str] = []
        self.capturing = False
        self.do = DoItems(self.events.append, self.set_capture)

    def set_capture(self, on: bool) -> None:
        self.capturing = on
        self.events.append(f"capture {on}")

    def run(self, items: tuple[MissionItem, ...], seq: int) -> int:
        return self.do.run(items, seq, capturing=self.capturing)


P = GuidanceParams.from_store(ParamStore())  # airspeeds within 12..22 m/s


def test_jump_is_taken_repeat_times_then_passed() -> None:
    items = (wp(0, 0, 100), do(MavCmd.DO_JUMP, param1=0, param2=2))
    s = _Sequencer()
    assert [s.run(items, 1) for _ in range(3)] == [0, 0, 2]
    assert s.events == ["Jump to item 0 (1/2)", "Jump to item 0 (2/2)"]
    s.do.new_mission()
    assert s.run(items, 1) == 0  # counters start again with a new mission


def test_speed_change_sets_an_airspeed_until_cleared() -> None:
    s = _Sequencer()
    assert s.do.airspeed(P, 0.0) is None
    s.run((do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=17.0),), 0)
    assert s.do.airspeed(P, 1.0) == 17.0 and s.events == ["Speed set to 17 m/s (air)"]
    s.run((do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=-1.0),), 0)
    assert s.do.airspeed(P, 1.0) == 17.0  # -1: no change
    s.run((do(MavCmd.DO_CHANGE_SPEED, param1=0.0, param2=30.0),), 0)
    assert s.do.airspeed(P, 1.0) == 22.0  # within FW_AIRSPD_MAX
    s.do.set_speed(None)
    assert s.do.airspeed(P, 1.0) is None


def test_ground_speed_is_flown_with_the_estimated_wind() -> None:
    s = _Sequencer()
    s.run((do(MavCmd.DO_CHANGE_SPEED, param1=1.0, param2=16.0),), 0)
    assert s.events == ["Speed set to 16 m/s (ground)"]
    plane = KinematicPlane(alt_rel=100.0, airspeed=15.0, wind_ne=(-3.0, 0.0))  # from the north
    for _ in range(500):  # 10 s of 50 Hz updates: the low-passed estimate has settled
        s.do.update(plane.state())
    assert s.do.airspeed(P, 0.0) == pytest.approx(19.0, abs=0.01)  # northbound: into the wind
    assert s.do.airspeed(P, math.pi) == pytest.approx(13.0, abs=0.01)  # southbound
    assert s.do.airspeed(P, math.pi / 2) == pytest.approx(math.hypot(16.0, 3.0), abs=0.01)


def test_capture_items_and_a_one_frame_shot() -> None:
    s = _Sequencer()
    items = (
        do(MavCmd.IMAGE_START_CAPTURE),
        do(MavCmd.IMAGE_STOP_CAPTURE),
        do(MavCmd.DO_DIGICAM_CONTROL, lat_deg=1.0),
    )
    assert [s.run(items, 0), s.run(items, 1)] == [1, 2]
    assert s.events == ["capture True", "capture False"]
    s.run(items, 2)
    assert s.capturing and s.do.single_frame
    s.do.update(KinematicPlane(alt_rel=100.0, airspeed=15.0).state())
    assert not s.capturing  # open for one guidance update: one camera frame
