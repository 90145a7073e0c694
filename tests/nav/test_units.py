"""Pieces of the filter on their own: fusion maths, extra sensors, status, determinism."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from air_sitl.frames import WGS84_A_M, WGS84_E2, euler2quat, geodetic2ecef, geodetic_lat_alt
from air_sitl.nav import NavFilter
from air_sitl.nav.ekf import ErrorStateEkf
from air_sitl.nav.fusion import FusionResult, result
from air_sitl.nav.params import NavParams
from air_sitl.nav.quaternion import rotation
from air_sitl.nav.sensors_extra import AirspeedSensor, Barometer, Magnetometer
from air_sitl.state import ImuSample, NavEstimate, VehicleState
from tests.nav.synthetic import Straight


def _ekf(seed: int) -> ErrorStateEkf:
    rng = np.random.default_rng(seed)
    ekf = ErrorStateEkf(NavParams(), 9.8)
    a = rng.standard_normal((17, 17))
    ekf.P = a @ a.T + np.eye(17)
    return ekf


def _fuse_direct(
    ekf: ErrorStateEkf, first: int, y: np.ndarray, R: np.ndarray, *, force: bool = False
) -> FusionResult:
    """A direct measurement of the error states ``first ..`` (H selects them): the column
    update for one, the block update for two or three (what position, velocity and height
    fusions run)."""
    k, P, x, dx, pending = ekf.kernels, ekf.P, ekf.x, ekf.dx, ekf.pending
    if len(y) == 1:
        outcome = k.fuse_column(P, x, first, R[0, 0], y[0], 100.0, force, dx, pending)
    else:
        outcome = k.fuse_block(P, x, first, y, R, 100.0, force, dx, pending)
    return result(ekf, outcome)


@pytest.mark.parametrize("m", [1, 2, 3])
def test_direct_updates_are_the_textbook_update(m: int) -> None:
    ekf = _ekf(m)
    P0 = ekf.P.copy()
    H = np.zeros((m, 17))
    for i in range(m):
        H[i, 3 + i] = 1.0
    R = np.array([[2.0, 0.3, -0.1], [0.3, 1.0, 0.2], [-0.1, 0.2, 1.5]])[:m, :m]
    y = np.array([0.5, -0.2, 0.1])[:m]
    S = H @ P0 @ H.T + R
    K = P0 @ H.T @ np.linalg.inv(S)
    res = _fuse_direct(ekf, 3, y, R)
    assert res.fused
    assert res.test_ratio == pytest.approx(float(y @ np.linalg.solve(S, y)) / 1e4)
    assert np.allclose(ekf.P, (np.eye(17) - K @ H) @ P0)
    assert np.allclose(ekf.pending, K @ y)
    assert ekf.v == pytest.approx((K @ y)[3:6])  # injected into the nominal state


@pytest.mark.parametrize("m", [1, 2, 3])
def test_direct_updates_refuse_an_unusable_innovation_covariance(m: int) -> None:
    ekf = _ekf(m)
    P0 = ekf.P.copy()
    R = -1e9 * np.eye(m)  # S = P block + R is not positive
    res = _fuse_direct(ekf, 3, np.full(m, 0.1), R, force=True)
    assert not res.fused and res.test_ratio == math.inf
    assert np.array_equal(ekf.P, P0) and not ekf.pending.any()


def test_a_late_position_is_compared_with_the_state_it_was_taken_at() -> None:
    """A position taken ``lag`` s ago is fused against the position predicted back along the
    velocity: the block update with that innovation, bit for bit."""
    ekf, twin = _ekf(5), _ekf(5)
    for e in (ekf, twin):
        e.x[0:6] = (10.0, 20.0, -100.0, 5.0, -3.0, 0.0)
    k, lag = ekf.kernels, 0.4
    R = np.array([[4.0, 0.5], [0.5, 9.0]])
    res = result(
        ekf, k.fuse_position(ekf.P, ekf.x, 12.0, 18.0, lag, 4.0, 0.5, 9.0, 100.0, ekf.dx,
                             ekf.pending),
    )  # fmt: skip
    y = np.array([12.0 - (10.0 - 5.0 * lag), 18.0 - (20.0 - -3.0 * lag)])
    expected = _fuse_direct(twin, 0, y, R)
    assert res == expected and res.fused
    assert np.array_equal(ekf.P, twin.P) and np.array_equal(ekf.x, twin.x)


def _fuse_row(ekf: ErrorStateEkf, h: np.ndarray, y: float, r: float, gate: float) -> FusionResult:
    """One scalar update with the dense Jacobian row ``h`` (what the models' fusions run)."""
    k = ekf.kernels
    return result(ekf, k.fuse_row(ekf.P, ekf.x, h, r, y, gate, False, ekf.dx, ekf.pending))


def test_fuse_row_is_the_textbook_update_and_gates() -> None:
    ekf = _ekf(2)
    P0 = ekf.P.copy()
    h = np.random.default_rng(3).standard_normal(17)
    s = float(h @ P0 @ h) + 0.5
    res = _fuse_row(ekf, h, 0.7, 0.5, gate=100.0)
    assert res.fused and res.test_ratio == pytest.approx(0.49 / s / 1e4)
    k = P0 @ h / s
    assert np.allclose(ekf.P, P0 - np.outer(k, h @ P0))
    assert np.allclose(ekf.pending, k * 0.7)
    big = _fuse_row(ekf, h, 1e6, 0.5, gate=5.0)
    assert not big.fused and big.test_ratio > 1.0


def test_geodetic_latitude_stops_at_its_fixed_point_with_the_six_step_bits() -> None:
    """Stopping once a step returns the same latitude gives what six steps give, bit for bit
    (the onboard estimate and the truth GNSS share the conversion)."""
    rng = np.random.default_rng(7)
    for _ in range(20000):
        x, y, z = geodetic2ecef(
            rng.uniform(-90, 90), rng.uniform(-180, 180), rng.uniform(-500, 2e4)
        )
        p = math.hypot(x, y)
        assert geodetic_lat_alt(p, z) == _six_steps(p, z)


def _six_steps(p: float, z: float) -> tuple[float, float]:
    """The conversion as it was: always six steps."""
    e2, a = WGS84_E2, WGS84_A_M
    lat, alt = math.atan2(z, p * (1.0 - e2)), 0.0
    for _ in range(6):
        sin_lat = math.sin(lat)
        n = a / math.sqrt(1.0 - e2 * sin_lat * sin_lat)
        near_pole = abs(lat) >= math.radians(89.0)
        alt = z / sin_lat - n * (1.0 - e2) if near_pole else p / math.cos(lat) - n
        lat = math.atan2(z, p * (1.0 - e2 * n / (n + alt)))
    return (lat, alt)


def test_integrate_holds_level_flight_and_turns() -> None:
    from air_sitl.nav.strapdown import integrate

    g = 9.8
    s = np.zeros(10)  # p, v, q
    s[3], s[6:10] = 15.0, euler2quat(0.0, 0.0, 0.0)
    for _ in range(50):  # 1 s of level flight at 15 m/s north, 20 ms deltas
        integrate(s, 0.0, 0.0, 0.0, 0.0, 0.0, -g * 0.02, 0.02, g)
    assert s[0:3].tolist() == pytest.approx([15.0, 0.0, 0.0], abs=1e-9)
    # A pure yaw rate of 0.1 rad/s for 10 s turns the attitude by 1 rad.
    s[6:10] = (1.0, 0.0, 0.0, 0.0)
    for _ in range(500):
        integrate(s, 0.0, 0.0, 0.002, 0.0, 0.0, 0.0, 0.02, g)
    assert 2.0 * math.atan2(s[9], s[6]) == pytest.approx(1.0)


def _state(t_ns: int) -> VehicleState:
    return VehicleState(
        sim_time_ns=t_ns,
        lat_deg=38.5,
        lon_deg=-121.5,
        alt_amsl_m=207.0,
        alt_agl_m=200.0,
        pos_ned_m=(0.0, 0.0, -200.0),
        q_body_to_ned_wxyz=euler2quat(0.0, 0.0, 0.5),
        roll_rad=0.0,
        pitch_rad=0.0,
        yaw_rad=0.5,
        vel_ned_m_s=(15.0, 0.0, 0.0),
        rate_frd_rad_s=(0.0, 0.0, 0.0),
        specific_force_frd_m_s2=(0.0, 0.0, -9.8),
        airspeed_m_s=15.0,
        on_ground=False,
    )


def test_extra_sensors_are_seeded_and_at_their_rates() -> None:
    def readings(seed: int) -> list[tuple[float, ...]]:
        baro, tas, mag = Barometer(seed=seed), AirspeedSensor(seed=seed), Magnetometer(seed=seed)
        out = []
        for k in range(2000):  # 10 s of 5 ms steps
            s = _state(k * 5_000_000)
            b, a, m = baro.sample(s), tas.sample(s), mag.sample(s)
            out.append((
                math.nan if b is None else b.alt_amsl_m,
                math.nan if a is None else a.airspeed_m_s,
                math.nan if m is None else m.heading_rad,
            ))  # fmt: skip
        return out

    one, again, other = readings(1), readings(1), readings(2)
    assert str(one) == str(again) and str(one) != str(other)
    arr = np.array(one)
    assert np.isfinite(arr[:, 0]).sum() == 200  # 20 Hz
    assert np.isfinite(arr[:, 1]).sum() == 100  # 10 Hz
    assert np.isfinite(arr[:, 2]).sum() == 100
    baro = arr[np.isfinite(arr[:, 0]), 0]
    assert abs(np.mean(baro) - 207.0) < 8.0 and 0.2 < np.std(baro) < 1.0
    heading = arr[np.isfinite(arr[:, 2]), 2]
    assert abs(np.mean(heading) - 0.5) < 0.1


def test_status_json_block() -> None:
    run = Straight()
    run.run(3.0)
    block = run.nav.status().to_json()
    json.dumps(block)
    assert block["source"] == "gnss"
    assert block["gnss"]["fused"] > 5
    assert block["aid"] == []
    assert block["flags"]["pos_horiz_abs"] is True


def test_estimate_before_alignment_has_no_valid_flags() -> None:
    from tests.nav.synthetic import HOME

    nav = NavFilter(HOME)
    e = nav.estimate()
    assert not e.flags.attitude and not e.flags.pos_horiz_rel
    assert e.lat_deg == pytest.approx(HOME.lat_deg)


def test_same_inputs_same_outputs() -> None:
    from tests.nav.flights import fly, record

    rec = record("UC-200", 40.0)  # test_flights' 180 s, if flown in this process, or its start
    _, one = fly(rec, deny_after_s=20.0, until_s=40.0, trace_every=1)
    _, two = fly(rec, deny_after_s=20.0, until_s=40.0, trace_every=1)
    assert one == two


def _perturbed(x: np.ndarray, k: int, eps: float) -> np.ndarray:
    """The nominal state moved by ``eps`` along error-state component k."""
    from air_sitl.nav.quaternion import rotate_global

    x = x.copy()
    if 3 <= k < 6:
        x[k] += eps
    elif 6 <= k < 9:
        dtheta = [0.0, 0.0, 0.0]
        dtheta[k - 6] = eps
        rotate_global(x, 6, *dtheta)
    elif k >= 15:
        x[k + 1] += eps  # wind: 16-17 in the nominal state
    return x


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_compass_and_airspeed_jacobians_match_finite_differences(seed: int) -> None:
    from air_sitl.nav.kernels import airspeed_model, heading_model, sideslip_model

    rng = np.random.default_rng(seed)
    roll, pitch, yaw = rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.3), rng.uniform(-3, 3)
    x = np.zeros(18)
    x[3:6] = (15 * math.cos(yaw) + 1.0, 15 * math.sin(yaw) - 2.0, 0.5)
    x[6:10] = euler2quat(roll, pitch, yaw)
    x[16:18] = (rng.normal(), rng.normal())
    eps = 1e-6
    for model in (sideslip_model, heading_model, airspeed_model):
        defined, _, h = model(x)
        assert defined
        for k in [*range(3, 9), 15, 16]:
            up = model(_perturbed(x, k, eps))[1]
            down = model(_perturbed(x, k, -eps))[1]
            numeric = (up - down) / (2 * eps)
            assert h[k] == pytest.approx(numeric, abs=1e-6), (model, k)
    # Undefined where the measurement has no meaning: still air, the nose straight up.
    calm = x.copy()
    calm[3:6], calm[16:18] = 0.0, 0.0
    assert not airspeed_model(calm)[0] and not sideslip_model(calm)[0]
    up = x.copy()
    up[6:10] = euler2quat(0.0, math.pi / 2, 0.0)
    assert not heading_model(up)[0]


def test_estimated_state_for_the_autopilot() -> None:
    from air_sitl.nav import estimated_state
    from tests.nav.synthetic import HEIGHT_M, HOME

    run = Straight()
    run.run(5.0)
    nav = run.nav
    est = nav.estimate()
    imu = ImuSample(
        sim_time_ns=est.sim_time_ns,
        gyro_frd_rad_s=(0.01, 0.0, 0.0),
        accel_frd_m_s2=(0.0, 0.0, -9.8),
        q_ahrs_body_to_ned_wxyz=(1.0, 0.0, 0.0, 0.0),
    )
    s = estimated_state(est, imu, airspeed_m_s=15.0, on_ground=False,
                        home_alt_amsl_m=HOME.alt_amsl_m)  # fmt: skip
    assert s.pos_ned_m == est.pos_ned_m and s.vel_ned_m_s == est.vel_ned_m_s
    assert s.alt_agl_m == pytest.approx(HEIGHT_M, abs=0.5)
    assert s.yaw_rad == pytest.approx(0.0, abs=0.02)
    assert s.rate_frd_rad_s[0] == pytest.approx(0.01 - est.gyro_bias_rad_s[0])


@pytest.mark.parametrize("cls", [VehicleState, NavEstimate])
def test_positional_builders_are_the_dataclass(cls: type) -> None:
    """The 200 Hz builders (a twin class with the same slots, then ``__class__``) make the
    object the dataclass makes: every field by position to its own slot (a new or reordered
    field fails here), frozen, of the dataclass's own type."""
    from dataclasses import FrozenInstanceError, fields

    from air_sitl.nav.vehicle import nav_estimate, vehicle_state

    build = {VehicleState: vehicle_state, NavEstimate: nav_estimate}[cls]
    values = {f.name: i + 0.25 for i, f in enumerate(fields(cls))}  # all distinct
    built = build(*values.values())
    assert type(built) is cls
    assert built == cls(**values)
    assert {f.name: getattr(built, f.name) for f in fields(built)} == values
    with pytest.raises(FrozenInstanceError):
        built.lat_deg = 0.0


def test_covariance_step_is_f_p_ft_plus_q() -> None:
    """The compiled sparse step equals the dense F P F' + Q of the error-state model."""
    ekf = _ekf(4)
    P0 = ekf.P.copy()
    ekf.q = euler2quat(0.2, -0.1, 1.3)
    T, dv = 0.08, (0.3, -0.2, -0.78)
    ekf.cov[:] = (T, *dv, 4.0)  # the deltas summed since the last step
    ekf.strapdown.covariance_step(ekf.x, ekf.P, ekf.cov, ekf.consts)
    assert not ekf.cov.any()

    def skew(x: float, y: float, z: float) -> np.ndarray:
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])

    R = np.array(rotation(*ekf.q)).reshape(3, 3)
    F = np.eye(17)
    F[0:3, 3:6] = T * np.eye(3)
    F[0:3, 6:9] = -skew(*(0.5 * T * d for d in dv))
    F[3:6, 6:9] = -skew(*dv)
    F[3:6, 12:15] = -R * T
    F[6:9, 9:12] = -R * T
    p, imu_dt = NavParams(), NavParams().imu_period_ns * 1e-9
    qv, qa = p.accel_noise_m_s2**2 * imu_dt * T, p.gyro_noise_rad_s**2 * imu_dt * T
    qbg, qba = p.gyro_bias_noise_rad_s2**2 * T, p.accel_bias_noise_m_s3**2 * T
    qw = p.wind_noise_m_s2**2 * T
    Q = [0, 0, 0, qv, qv, qv, qa, qa, qa, qbg, qbg, qbg, qba, qba, qba, qw, qw]
    expected = F @ P0 @ F.T + np.diag(Q)
    assert np.allclose(ekf.P, 0.5 * (expected + expected.T), rtol=1e-12, atol=1e-12)
    assert np.array_equal(ekf.P, ekf.P.T)
