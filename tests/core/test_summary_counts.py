"""summary.json counts: every reached item (several in one step, DO_JUMP back to where the
aircraft is), and "n/a" rather than 0.0 for tracking errors never measured."""

from __future__ import annotations

import io
from pathlib import Path

from air_sitl.autopilot.autopilot import Autopilot
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.target import ControlTarget
from air_sitl.flightlog import FlightStats
from air_sitl.mission.items import MavCmd
from air_sitl.progress import print_summary
from air_sitl.state import SimSample, VehicleState
from tests.autopilot.sim import HOME, KinematicPlane, do, mission, wp


class _PassThrough:
    """A controller that hands the target to the kinematic plane unchanged."""

    def update(self, state: VehicleState, target: ControlTarget) -> ControlTarget:
        return target


def test_items_finishing_in_one_step_are_all_counted_before_the_flight_stops() -> None:
    # Waypoints 1 and 2 are the same point: both are reached in one guidance step; the jump
    # back to 2 reaches it again at once and the mission ends in that same step.
    m = mission(
        wp(0, 0, 40, MavCmd.NAV_TAKEOFF),
        wp(600, 0, 40),
        wp(600, 0, 40),
        do(MavCmd.DO_JUMP, param1=2.0, param2=1.0),
    )
    plane = KinematicPlane()
    ap = Autopilot(m, HOME, ParamStore(), _PassThrough())  # type: ignore[arg-type]
    stats = FlightStats(waypoints_total=3)
    reached: list[int] = []
    state = plane.state()
    for _ in range(200_000):
        target, status = ap.update(state)
        stats.add(SimSample(state=state, autopilot=status, imu=None, gps=None))  # type: ignore[arg-type]
        if status.reached_seq >= 0:
            reached.append(status.reached_seq)
        if status.mission_completed:  # where the runner stops
            break
        state = plane.step(target)  # type: ignore[arg-type]
    else:
        raise AssertionError("mission never completed")
    # The truth: items 0, 1, 2, then 2 again after the jump, all reported before the stop.
    assert reached == [0, 1, 2, 2]
    assert stats.summary(1.0)["waypoints_reached"] == 3


def test_unmeasured_errors_print_as_not_available(tmp_path: Path) -> None:
    summary = {
        "plan": "x",
        "mission_completed": False,
        "waypoints_reached": 0,
        "waypoints_total": 2,
        "capture_frames": 0,
        "capture_distance_m": 0.0,
        "max_cross_track_m": None,
        "max_alt_error_m": None,
        "sim_time_s": 1.0,
        "wall_time_s": 1.0,
        "realtime_factor": 1.0,
    }
    out = io.StringIO()
    print_summary(summary, tmp_path, out)
    text = out.getvalue()
    assert "max cross-track  n/a" in text and "max alt error    n/a" in text
    out = io.StringIO()
    print_summary({**summary, "max_cross_track_m": 3.25, "max_alt_error_m": 0.0}, tmp_path, out)
    assert "max cross-track  3.2 m" in out.getvalue() or "3.3 m" in out.getvalue()
    assert "max alt error    0.0 m" in out.getvalue()


def test_the_printed_summary_says_how_the_flight_ended(tmp_path: Path) -> None:
    base = {
        "plan": "x", "waypoints_reached": 1, "waypoints_total": 2, "capture_frames": 0,
        "capture_distance_m": 0.0, "max_cross_track_m": None, "max_alt_error_m": None,
        "sim_time_s": 14400.0, "wall_time_s": 1.0, "realtime_factor": 1.0, "landed": False,
    }  # fmt: skip
    cases = [
        ({"mission_completed": False, "crashed": None}, "time limit (--max-sim-time)"),
        (
            {
                "mission_completed": False,
                "crashed": {
                    "sim_time_s": 61.5,
                    "lat_deg": 54.69,
                    "lon_deg": 25.28,
                    "reason": "ground contact outside a landing",
                },
            },
            "CRASHED at 61.5 s, 54.690000, 25.280000: ground contact outside a landing",
        ),
        ({"mission_completed": True, "crashed": None, "landed": True}, "completed, landed"),
    ]
    for extra, expected in cases:
        out = io.StringIO()
        print_summary({**base, **extra}, tmp_path, out)
        assert expected in out.getvalue().splitlines()[0]
