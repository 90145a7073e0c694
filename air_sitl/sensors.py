"""Simulated on-board sensors: IMU (gyro, accelerometer), AHRS attitude and GNSS.

Deterministic from a seed: noise comes from numpy's PCG64 drawn in blocks, so the same seed and
the same sequence of states give the same readings. Truth comes in as a VehicleState; nothing
here reads the wall clock.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from air_sitl import sensors_kernel as sk
from air_sitl.clock import NS_PER_S
from air_sitl.frames import LocalNed
from air_sitl.state import (
    GeoPoint,
    GpsFix,
    ImuSample,
    VehicleState,
    imu_sample,
    positional_builder,
)


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


class NormalRows:
    """Rows of standard normal draws served one at a time from pre-drawn blocks (fast, seeded;
    the stream does not depend on the block size): as lists (:meth:`row`) or as an index into
    the block's array (:meth:`index`, for the compiled sensors). ``next_index`` is the next
    row's index while it is below ``len(array)`` (a 200 Hz caller may take it itself)."""

    __slots__ = ("_block", "_rng", "_width", "array", "next_index")

    def __init__(self, rng: np.random.Generator, width: int) -> None:
        self._rng = rng
        self._width = width
        self.array = np.zeros((0, width))
        self._block: list[list[float]] | None = []
        self.next_index = 0

    def index(self) -> int:
        """The next row's index in :attr:`array`."""
        if self.next_index >= len(self.array):
            self.array = self._rng.standard_normal((2048, self._width))
            self._block = None
            self.next_index = 0
        self.next_index += 1
        return self.next_index - 1

    def row(self) -> list[float]:
        """The next row."""
        i = self.index()
        if self._block is None:
            self._block = self.array.tolist()
        return self._block[i]


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
        self._local_home: GeoPoint | None = None  # the home of _local (made at the first fix)
        self._local: LocalNed | None = None
        self.step_s = step_ns / NS_PER_S
        self.gps_period_ns = round(NS_PER_S / self.noise.gps_rate_hz)
        self.gps_denied_ns = gps_denied_ns
        root = np.random.SeedSequence([seed, 0x5E7502])
        bias_seq, step_seq, gps_seq = root.spawn(3)
        n = self.noise
        b = np.random.default_rng(bias_seq).standard_normal(6).tolist()
        # The slowly varying errors (sensors_kernel: gyro bias, accelerometer bias, AHRS
        # drift) and the noise figures, as the compiled IMU takes them.
        self._errors = np.array(
            [v * n.gyro_bias_rad_s for v in b[:3]] + [v * n.accel_bias_m_s2 for v in b[3:]]
            + [0.0, 0.0, 0.0]
        )  # fmt: skip
        # Per step: bias walk (3), gyro noise (3), accel noise (3), AHRS drift (3), jitter (3).
        self._step_noise = NormalRows(np.random.default_rng(step_seq), 15)
        self._gps = NormalRows(np.random.default_rng(gps_seq), 6)
        sqrt_dt = math.sqrt(self.step_s)
        self._figures = np.array(  # in sensors_kernel's order (WALK ... DRIFT_LIMIT)
            [n.gyro_bias_walk_rad_s_sqrt_s * sqrt_dt, n.gyro_noise_rad_s, n.accel_noise_m_s2,
             n.ahrs_drift_rad_sqrt_s * sqrt_dt, n.ahrs_noise_rad, n.ahrs_drift_limit_rad]
        )  # fmt: skip

    def gps_denied(self, sim_time_ns: int) -> bool:
        """True inside any GNSS denial window [start, end)."""
        if not self.gps_denied_ns:
            return False  # none (the filter asks at 50 Hz)
        return any(a <= sim_time_ns < b for a, b in self.gps_denied_ns)

    def sample(self, state: VehicleState) -> tuple[ImuSample, GpsFix | None]:
        """Sensor readings for one physics step (call once per step, in order)."""
        rows = self._step_noise
        i = rows.next_index  # rows.index(), the common case written out (a 200 Hz path)
        if i < len(rows.array):
            rows.next_index = i + 1
        else:
            i = rows.index()
        gyro, accel, ahrs = sk.imu(
            rows.array, i, self._errors, self._figures, state.rate_frd_rad_s,
            state.specific_force_frd_m_s2, state.q_body_to_ned_wxyz,
        )  # fmt: skip
        imu = imu_sample(state.sim_time_ns, gyro, accel, ahrs)  # ImuSample's field order
        gps = None
        if state.sim_time_ns % self.gps_period_ns == 0:
            # Draw even while denied so denial windows do not shift later noise.
            g = self._gps.row()
            if not self.gps_denied(state.sim_time_ns):
                gps = self._fix(state, g)
        return imu, gps

    def _fix(self, state: VehicleState, g: list[float]) -> GpsFix:
        n = self.noise
        north, east, down = state.pos_ned_m
        home = self.home
        local = self._local
        if local is None or self._local_home is not home:  # ned2geodetic's frame, made once
            self._local_home = home
            local = self._local = LocalNed(home.lat_deg, home.lon_deg, home.alt_amsl_m)
        lat, lon, alt = local.to_geodetic(
            north + g[0] * n.gps_horizontal_m,
            east + g[1] * n.gps_horizontal_m,
            down + g[2] * n.gps_vertical_m,
        )
        v = state.vel_ned_m_s
        return gps_fix(  # positional, in GpsFix's field order (5 Hz)
            state.sim_time_ns,
            lat,
            lon,
            alt,
            (
                v[0] + g[3] * n.gps_velocity_m_s,
                v[1] + g[4] * n.gps_velocity_m_s,
                v[2] + g[5] * n.gps_velocity_m_s,
            ),
            3,
            14,
            max(n.gps_horizontal_m, 0.01),
            max(n.gps_vertical_m, 0.01),
        )


gps_fix: Callable[..., GpsFix] = positional_builder(GpsFix)
