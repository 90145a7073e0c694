"""Summary metrics and the trajectory file, fed with constructed samples."""

from __future__ import annotations

import math
from pathlib import Path

from vehicle_states import airborne_state

from air_sitl.clock import PHYSICS_STEP_NS
from air_sitl.flightlog import TRAJECTORY_COLUMNS, FlightStats, TrajectoryWriter
from air_sitl.sinks import FlightResult
from air_sitl.state import AutopilotStatus, FlightMode, ImuSample, SimSample


def _sample(k: int, *, capturing: bool, xt: float = 1.0, settled: bool = True) -> SimSample:
    t = k * PHYSICS_STEP_NS
    north = 15.0 * t / 1e9
    state = airborne_state(
        t,
        lat_deg=50.0,
        lon_deg=8.0,
        alt_amsl_m=300.0,
        alt_agl_m=200.0,
        pos_ned_m=(north, 0.0, -200.0),
    )
    status = AutopilotStatus(
        mode=FlightMode.MISSION,
        armed=True,
        current_seq=2,
        capturing=capturing,
        mission_completed=False,
        reached_seq=2 if k == 10 else -1,
        cross_track_m=xt,
        alt_error_m=-xt / 2,
        tracking_settled=settled,
    )
    imu = ImuSample(
        sim_time_ns=t,
        gyro_frd_rad_s=(0.0, 0.0, 0.0),
        accel_frd_m_s2=(0.0, 0.0, -9.81),
        q_ahrs_body_to_ned_wxyz=state.q_body_to_ned_wxyz,
    )
    return SimSample(state=state, autopilot=status, imu=imu, gps=None)


def test_capture_frames_and_distance_count_50hz_samples_in_window() -> None:
    stats = FlightStats(waypoints_total=5)
    for k in range(400):  # 2 s at 200 Hz; capture during the second second
        stats.add(_sample(k, capturing=k >= 200, xt=3.0 if k == 50 else 1.0, settled=k != 60))
    s = stats.summary(wall_time_s=0.5)
    assert s["capture_frames"] == 50
    assert math.isclose(s["capture_distance_m"], 15.0 * 49 / 50, rel_tol=1e-9)
    assert s["max_cross_track_m"] == 3.0
    assert s["max_alt_error_m"] == 1.5
    assert s["waypoints_reached"] == 1
    assert s["waypoints_total"] == 5
    assert s["mission_completed"] is False


def test_unsettled_errors_are_not_counted() -> None:
    stats = FlightStats(waypoints_total=1)
    stats.add(_sample(0, capturing=False, xt=99.0, settled=False))
    summary = stats.summary(1.0)
    # Nothing measured is null ("n/a"), not a perfect 0.0.
    assert summary["max_cross_track_m"] is None
    assert summary["max_alt_error_m"] is None


def test_trajectory_writes_50hz_rows(tmp_path: Path) -> None:
    writer = TrajectoryWriter(tmp_path / "trajectory.csv")
    for k in range(40):
        writer.on_sample(_sample(k, capturing=False))
    writer.close(FlightResult(mission_completed=True, sim_time_ns=0, wall_time_s=0.0))
    lines = (tmp_path / "trajectory.csv").read_text().splitlines()
    assert lines[0].split(",") == list(TRAJECTORY_COLUMNS)
    assert len(lines) == 1 + 10
    assert [int(line.split(",")[0]) for line in lines[1:3]] == [0, 20_000_000]
