"""Simulated on-board sensors: IMU (gyro, accelerometer), AHRS attitude and GNSS.

Deterministic from a seed: noise comes from numpy's PCG64 drawn in blocks, so the same seed and
the same sequence of states give the same readings. Truth comes in as a VehicleState; nothing
here reads the wall clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from air_sitl.frames import euler2quat, ned2geodetic, quat_multiply, quat_normalize
from air_sitl.state import GeoPoint, GpsFix, ImuSample, Vec3, VehicleState

NS_PER_S = 1_000_000_000


@dataclass(frozen=True, slots=True, kw_only=True)
class SensorNoise:
    """Noise figures of a small MEMS IMU and a consumer GNSS receiver (1-sigma)."""

    gyro_noise_rad_s: float = 0.003  # white noise per sample at 200 Hz
    gyro_bias_rad_s: float = 0.002  # constant turn-on bias, drawn once per flight
    gyro_bias_walk_rad_s_sqrt_s: float = 0.0001  # bias random walk
    accel_noise_m_s2: float = 0.05
    accel_bias_m_s2: float = 0.05
    ahrs_noise_rad: float = 0.002  # per-sample attitude jitter of the AHRS output
    ahrs_drift_rad_sqrt_s: float = 0.0005  # slow random-walk drift of the AHRS attitude
    ahrs_drift_limit_rad: float = 0.02  # the filter's gravity/GNSS aiding bounds the drift
    gps_rate_hz: float = 5.0
    gps_horizontal_m: float = 1.5
    gps_vertical_m: float = 3.0
    gps_velocity_m_s: float = 0.1

    def scaled(self, factor: float) -> SensorNoise:
        """All noise figures times ``factor`` (0 gives perfect sensors)."""
        return SensorNoise(
            gyro_noise_rad_s=self.gyro_noise_rad_s * factor,
            gyro_bias_rad_s=self.gyro_bias_rad_s * factor,
            gyro_bias_walk_rad_s_sqrt_s=self.gyro_bias_walk_rad_s_sqrt_s * factor,
            accel_noise_m_s2=self.accel_noise_m_s2 * factor,
            accel_bias_m_s2=self.accel_bias_m_s2 * factor,
            ahrs_noise_rad=self.ahrs_noise_rad * factor,
            ahrs_drift_rad_sqrt_s=self.ahrs_drift_rad_sqrt_s * factor,
            ahrs_drift_limit_rad=self.ahrs_drift_limit_rad,
            gps_rate_hz=self.gps_rate_hz,
            gps_horizontal_m=self.gps_horizontal_m * factor,
            gps_vertical_m=self.gps_vertical_m * factor,
            gps_velocity_m_s=self.gps_velocity_m_s * factor,
        )


class _Normals:
    """Standard normal draws served one at a time from pre-drawn blocks (fast and seeded)."""

    __slots__ = ("_block", "_i", "_rng")

    def __init__(self, rng: np.random.Generator) -> None:
        self._rng = rng
        self._block: list[float] = []
        self._i = 0

    def next3(self) -> Vec3:
        if self._i + 3 > len(self._block):
            self._block = self._rng.standard_normal(3 * 4096).tolist()
            self._i = 0
        i = self._i
        self._i = i + 3
        b = self._block
        return (b[i], b[i + 1], b[i + 2])


class SensorSuite:
    """IMU + AHRS at every physics step, GNSS at ``gps_rate_hz``; optional GNSS denial."""

    def __init__(
        self,
        home: GeoPoint,
        *,
        seed: int,
        step_ns: int,
        noise: SensorNoise | None = None,
        gps_denied_ns: tuple[tuple[int, int], ...] = (),
    ) -> None:
        self.noise = noise or SensorNoise()
        self.home = home
        self.step_s = step_ns / NS_PER_S
        self.gps_period_ns = round(NS_PER_S / self.noise.gps_rate_hz)
        self.gps_denied_ns = gps_denied_ns
        root = np.random.SeedSequence([seed, 0x5E7502])
        imu_seq, ahrs_seq, gps_seq = root.spawn(3)
        self._imu = _Normals(np.random.default_rng(imu_seq))
        self._ahrs = _Normals(np.random.default_rng(ahrs_seq))
        self._gps = _Normals(np.random.default_rng(gps_seq))
        n = self.noise
        b = self._imu.next3()
        self._gyro_bias = [
            b[0] * n.gyro_bias_rad_s,
            b[1] * n.gyro_bias_rad_s,
            b[2] * n.gyro_bias_rad_s,
        ]
        a = self._imu.next3()
        self._accel_bias = (
            a[0] * n.accel_bias_m_s2,
            a[1] * n.accel_bias_m_s2,
            a[2] * n.accel_bias_m_s2,
        )
        self._ahrs_drift = [0.0, 0.0, 0.0]

    def gps_denied(self, sim_time_ns: int) -> bool:
        """True inside any GNSS denial window [start, end)."""
        return any(a <= sim_time_ns < b for a, b in self.gps_denied_ns)

    def sample(self, state: VehicleState) -> tuple[ImuSample, GpsFix | None]:
        """Sensor readings for one physics step (call once per step, in order)."""
        n = self.noise
        sqrt_dt = math.sqrt(self.step_s)
        walk = self._imu.next3()
        for k in range(3):
            self._gyro_bias[k] += walk[k] * n.gyro_bias_walk_rad_s_sqrt_s * sqrt_dt
        gn = self._imu.next3()
        an = self._imu.next3()
        p, q, r = state.rate_frd_rad_s
        fx, fy, fz = state.specific_force_frd_m_s2
        gb = self._gyro_bias
        ab = self._accel_bias
        gyro = (
            p + gb[0] + gn[0] * n.gyro_noise_rad_s,
            q + gb[1] + gn[1] * n.gyro_noise_rad_s,
            r + gb[2] + gn[2] * n.gyro_noise_rad_s,
        )
        accel = (
            fx + ab[0] + an[0] * n.accel_noise_m_s2,
            fy + ab[1] + an[1] * n.accel_noise_m_s2,
            fz + ab[2] + an[2] * n.accel_noise_m_s2,
        )
        dn = self._ahrs.next3()
        jn = self._ahrs.next3()
        lim = n.ahrs_drift_limit_rad
        for k in range(3):
            d = self._ahrs_drift[k] + dn[k] * n.ahrs_drift_rad_sqrt_s * sqrt_dt
            self._ahrs_drift[k] = max(-lim, min(lim, d))
        err = euler2quat(
            self._ahrs_drift[0] + jn[0] * n.ahrs_noise_rad,
            self._ahrs_drift[1] + jn[1] * n.ahrs_noise_rad,
            self._ahrs_drift[2] + jn[2] * n.ahrs_noise_rad,
        )
        q_ahrs = quat_normalize(quat_multiply(state.q_body_to_ned_wxyz, err))
        imu = ImuSample(
            sim_time_ns=state.sim_time_ns,
            gyro_frd_rad_s=gyro,
            accel_frd_m_s2=accel,
            q_ahrs_body_to_ned_wxyz=q_ahrs,
        )
        gps = None
        if state.sim_time_ns % self.gps_period_ns == 0:
            # Draw even while denied so denial windows do not shift later noise.
            pn = self._gps.next3()
            vn = self._gps.next3()
            if not self.gps_denied(state.sim_time_ns):
                gps = self._fix(state, pn, vn)
        return imu, gps

    def _fix(self, state: VehicleState, pn: Vec3, vn: Vec3) -> GpsFix:
        n = self.noise
        north, east, down = state.pos_ned_m
        lat, lon, alt = ned2geodetic(
            north + pn[0] * n.gps_horizontal_m,
            east + pn[1] * n.gps_horizontal_m,
            down + pn[2] * n.gps_vertical_m,
            self.home.lat_deg,
            self.home.lon_deg,
            self.home.alt_amsl_m,
        )
        v = state.vel_ned_m_s
        return GpsFix(
            sim_time_ns=state.sim_time_ns,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt,
            vel_ned_m_s=(
                v[0] + vn[0] * n.gps_velocity_m_s,
                v[1] + vn[1] * n.gps_velocity_m_s,
                v[2] + vn[2] * n.gps_velocity_m_s,
            ),
            fix_type=3,
            satellites=14,
            eph_m=max(n.gps_horizontal_m, 0.01),
            epv_m=max(n.gps_vertical_m, 0.01),
        )
