"""The error-state EKF core: nominal state, prediction, covariance, corrections and resets.

Nominal state: position and velocity NED from home, attitude quaternion body->NED, gyro and
accelerometer biases (body FRD), horizontal wind (NED, the velocity of the air). Error state
(17, Sola 2017 with a *global* attitude error: the true attitude is ``exp(dtheta) * q``,
dtheta in NED, which keeps the IMU-delta Jacobians simple):

    0-2 dp   3-5 dv   6-8 dtheta   9-11 d gyro bias   12-14 d accel bias   15-16 d wind (N, E)

The IMU arrives as summed delta angles/velocities (EKF2's downsampling); the covariance is
propagated less often than the nominal state, with the deltas summed again. The numerics are
compiled (:mod:`air_sitl.nav.strapdown`, :mod:`air_sitl.nav.kernels`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.nav.params import NavParams

N_STATES = 17
POS, VEL, ATT, BG, BA, WIND = 0, 3, 6, 9, 12, 15  # in the error state

Matrix = npt.NDArray[np.float64]
Vector = npt.NDArray[np.float64]


def normal_gravity_m_s2(lat_deg: float, alt_m: float) -> float:
    """WGS84 normal gravity (Somigliana) with the free-air gradient."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    g0 = 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2)
    return g0 - 3.086e-6 * alt_m


class ErrorStateEkf:
    """Nominal state ``x`` (layout in :mod:`air_sitl.nav.strapdown`) and covariance ``P`` as
    float64 arrays, worked on by compiled kernels; no time handling here."""

    def __init__(self, params: NavParams, gravity_m_s2: float) -> None:
        # The kernels (machine code built once, loaded in milliseconds: air_sitl.compiled;
        # else numba, 0.5 s to import and its cached code to load) only where a filter runs:
        # `air-sitl --help` and --nav truth flights never load them.
        from air_sitl.compiled import say_when_compiling
        from air_sitl.nav import kernels, quaternion, strapdown

        say_when_compiling("the navigation filter", kernels.predict_covariance, strapdown.advance)
        kernels.warm()
        strapdown.warm()
        self.kernels = kernels
        self.strapdown = strapdown
        self._rotation = quaternion.rotation
        self.params = params
        self.g = gravity_m_s2
        self.x: Vector = np.zeros(strapdown.NX)
        self.x[6] = 1.0  # level, facing north
        self.P: Matrix = np.zeros((N_STATES, N_STATES))
        # Deltas summed since the last covariance step: dt, NED delta velocity, count.
        self.cov: Vector = np.zeros(5)
        # Gravity, the process noise densities (per second of a covariance step), the filter
        # periods per covariance step (see strapdown).
        imu_dt = params.imu_period_ns / 1e9
        self.consts: Vector = np.array(
            (
                gravity_m_s2,
                params.accel_noise_m_s2**2 * imu_dt,
                params.gyro_noise_rad_s**2 * imu_dt,
                params.gyro_bias_noise_rad_s2**2,
                params.accel_bias_noise_m_s3**2,
                params.wind_noise_m_s2**2,
                params.cov_every,
            ),
            dtype=np.float64,
        )
        # Corrections since the output predictor last took them (summed: first order).
        self.pending: Vector = np.zeros(N_STATES)
        self.dx: Vector = np.zeros(N_STATES)  # the last measurement update's correction
        self.corrected = False  # pending holds something

    # Parts of the nominal state as tuples, for the control logic of the sources (resets,
    # delayed innovations); the hot paths work on ``x`` in compiled code.
    @property
    def p(self) -> tuple[float, float, float]:
        x = self.x
        return (x.item(0), x.item(1), x.item(2))

    @property
    def v(self) -> tuple[float, float, float]:
        x = self.x
        return (x.item(3), x.item(4), x.item(5))

    @property
    def q(self) -> tuple[float, float, float, float]:
        x = self.x
        return (x.item(6), x.item(7), x.item(8), x.item(9))

    @q.setter
    def q(self, q: tuple[float, float, float, float]) -> None:
        self.x[6:10] = q

    def rotation(self) -> tuple[float, ...]:
        """The body->NED rotation matrix of the attitude, row-major (9 floats)."""
        return self._rotation(*self.q)  # type: ignore[no-any-return]

    @property
    def wind(self) -> tuple[float, float]:
        return (self.x.item(16), self.x.item(17))

    def init_covariance(self) -> None:
        p = self.params
        d = [p.init_pos_m**2] * 3 + [p.init_vel_m_s**2] * 3
        d += [p.init_tilt_rad**2, p.init_tilt_rad**2, p.init_yaw_rad**2]
        d += [p.init_gyro_bias_rad_s**2] * 3 + [p.init_accel_bias_m_s2**2] * 3
        d += [p.init_wind_m_s**2] * 2
        self.P = np.diag(np.array(d, dtype=np.float64))

    def correct(self, dx: list[float]) -> None:
        """Inject an error-state correction into the nominal state and the pending sum."""
        self.pending += dx
        self.kernels.inject(self.x, np.array(dx, dtype=np.float64))
        self.corrected = True

    def reset_states(self, first: int, values: tuple[float, ...], variance: float) -> list[float]:
        """Set position/velocity/wind components and their variance; returns the jump applied.

        Cross-covariances of the reset states are zeroed (EKF2's resetHorizontalPosition).
        """
        dx = [0.0] * N_STATES
        current = (*self.p, *self.v, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, *self.wind)
        for i, value in enumerate(values):
            k = first + i
            dx[k] = value - current[k]
            self.P[k, :] = 0.0
            self.P[:, k] = 0.0
            self.P[k, k] = variance
        self.correct(dx)
        return dx

    def reset_yaw(self, yaw_rad: float, variance: float) -> float:
        """Set the heading keeping the tilt; returns the rotation applied about NED down."""
        w, x, y, z = self.q
        yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        delta = math.remainder(yaw_rad - yaw, 2.0 * math.pi)
        dx = [0.0] * N_STATES
        dx[ATT + 2] = delta
        self.correct(dx)
        self.P[ATT + 2, :] = 0.0
        self.P[:, ATT + 2] = 0.0
        self.P[ATT + 2, ATT + 2] = variance
        return delta
