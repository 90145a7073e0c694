"""The simulated IMU/AHRS/GNSS: determinism, noise levels, rates, denial windows."""

from __future__ import annotations

import math
import statistics

from vehicle_states import airborne_state

from air_sitl.clock import PHYSICS_STEP_NS
from air_sitl.frames import quat2euler
from air_sitl.sensors import SensorNoise, SensorSuite
from air_sitl.state import GeoPoint, VehicleState

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


def _state(t_ns: int) -> VehicleState:
    return airborne_state(
        t_ns,
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=HOME.alt_amsl_m + 200.0,
        alt_agl_m=200.0,
        pos_ned_m=(0.0, 0.0, -200.0),
        rpy_rad=(0.1, 0.05, 1.0),
        vel_ned_m_s=(10.0, 5.0, 0.0),
        rate_frd_rad_s=(0.01, 0.02, 0.03),
    )


def _run(suite: SensorSuite, steps: int) -> list[tuple[object, object]]:
    return [suite.sample(_state(k * PHYSICS_STEP_NS)) for k in range(steps)]


def test_same_seed_same_readings_other_seed_differs() -> None:
    a = _run(SensorSuite(HOME, seed=3, step_ns=PHYSICS_STEP_NS), 400)
    b = _run(SensorSuite(HOME, seed=3, step_ns=PHYSICS_STEP_NS), 400)
    c = _run(SensorSuite(HOME, seed=4, step_ns=PHYSICS_STEP_NS), 400)
    assert a == b
    assert a != c


def test_noise_levels_and_gps_rate() -> None:
    suite = SensorSuite(HOME, seed=1, step_ns=PHYSICS_STEP_NS)
    readings = _run(suite, 2000)  # 10 s
    gyro_x = [imu.gyro_frd_rad_s[0] for imu, _ in readings]  # type: ignore[attr-defined]
    assert 0.002 < statistics.stdev(gyro_x) < 0.005
    assert abs(statistics.mean(gyro_x) - 0.01) < 0.01  # bias of a few mrad/s
    fixes = [gps for _, gps in readings if gps is not None]
    assert len(fixes) == 50  # 5 Hz for 10 s
    rolls = [quat2euler(imu.q_ahrs_body_to_ned_wxyz)[0] for imu, _ in readings]  # type: ignore[attr-defined]
    assert max(abs(r - 0.1) for r in rolls) < 0.04
    horiz = [math.hypot(f.lat_deg - HOME.lat_deg, f.lon_deg - HOME.lon_deg) for f in fixes]  # type: ignore[attr-defined]
    assert max(horiz) < 1e-4  # a few metres


def test_zero_noise_gives_truth() -> None:
    suite = SensorSuite(HOME, seed=1, step_ns=PHYSICS_STEP_NS, noise=SensorNoise().scaled(0.0))
    imu, gps = suite.sample(_state(0))
    assert imu.gyro_frd_rad_s == (0.01, 0.02, 0.03)
    assert imu.accel_frd_m_s2 == (0.0, 0.0, -9.81)
    assert gps is not None
    assert abs(gps.alt_amsl_m - 320.0) < 1e-6


def test_gps_denial_window_drops_fixes_without_shifting_noise() -> None:
    window = ((2 * 10**9, 4 * 10**9),)
    denied = SensorSuite(HOME, seed=5, step_ns=PHYSICS_STEP_NS, gps_denied_ns=window)
    free = SensorSuite(HOME, seed=5, step_ns=PHYSICS_STEP_NS)
    a = _run(denied, 1200)
    b = _run(free, 1200)
    times = [gps.sim_time_ns for _, gps in a if gps is not None]  # type: ignore[attr-defined]
    assert not [t for t in times if 2 * 10**9 <= t < 4 * 10**9]
    assert len(times) == 30 - 10
    assert a[1000] == b[1000]  # after the window: identical readings
