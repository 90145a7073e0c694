"""The error-state EKF core: nominal state, prediction, covariance, corrections and resets.

Nominal state (plain floats: cheap in CPython): position and velocity NED from home, attitude
quaternion body->NED, gyro and accelerometer biases (body FRD), horizontal wind (NED, the
velocity of the air). Error state (17, Sola 2017 with a *global* attitude error: the true
attitude is ``exp(dtheta) * q``, dtheta in NED, which keeps the IMU-delta Jacobians simple):

    0-2 dp   3-5 dv   6-8 dtheta   9-11 d gyro bias   12-14 d accel bias   15-16 d wind (N, E)

The IMU arrives as summed delta angles/velocities (EKF2's downsampling); the covariance is
propagated less often than the nominal state, with the deltas summed again.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.nav.params import NavParams

N_STATES = 17
POS, VEL, ATT, BG, BA, WIND = 0, 3, 6, 9, 12, 15

Matrix = npt.NDArray[np.float64]
NominalState = tuple[
    tuple[float, float, float], tuple[float, float, float], tuple[float, float, float, float]
]


def normal_gravity_m_s2(lat_deg: float, alt_m: float) -> float:
    """WGS84 normal gravity (Somigliana) with the free-air gradient."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    g0 = 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2)
    return g0 - 3.086e-6 * alt_m


def integrate(
    p: tuple[float, float, float],
    v: tuple[float, float, float],
    q: tuple[float, float, float, float],
    dang: tuple[float, float, float],
    dvel: tuple[float, float, float],
    dt: float,
    g: float,
) -> tuple[
    tuple[float, float, float],
    tuple[float, float, float],
    tuple[float, float, float, float],
    tuple[float, float, float],
]:
    """One strapdown step with bias-corrected deltas: (p, v, q, delta v in NED without g).

    The velocity delta is rotated with the mid-interval attitude (first-order sculling), the
    quaternion advanced with the exact rotation of the delta angle.
    """
    ax, ay, az = dang
    # Rotate dv by the half-step rotation first: dv + 0.5 * dang x dv.
    dx = dvel[0] + 0.5 * (ay * dvel[2] - az * dvel[1])
    dy = dvel[1] + 0.5 * (az * dvel[0] - ax * dvel[2])
    dz = dvel[2] + 0.5 * (ax * dvel[1] - ay * dvel[0])
    w, x, y, z = q
    tx = 2.0 * (y * dz - z * dy)
    ty = 2.0 * (z * dx - x * dz)
    tz = 2.0 * (x * dy - y * dx)
    nx = dx + w * tx + (y * tz - z * ty)
    ny = dy + w * ty + (z * tx - x * tz)
    nz = dz + w * tz + (x * ty - y * tx)
    angle2 = ax * ax + ay * ay + az * az
    if angle2 > 1e-12:
        angle = math.sqrt(angle2)
        s = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    else:
        s = 0.5
        c = 1.0 - angle2 / 8.0
    v0, v1, v2 = v
    w0 = v0 + nx
    w1 = v1 + ny
    w2 = v2 + nz + g * dt
    h = 0.5 * dt
    return (
        (p[0] + (v0 + w0) * h, p[1] + (v1 + w1) * h, p[2] + (v2 + w2) * h),
        (w0, w1, w2),
        unit_product(w, x, y, z, c, ax * s, ay * s, az * s),  # q * exp(dang): body frame
        (nx, ny, nz),
    )


def rotation_matrix(q: tuple[float, float, float, float]) -> tuple[float, ...]:
    """Row-major body->NED rotation matrix of q (9 floats)."""
    w, x, y, z = q
    return (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )


def rotate_global(
    q: tuple[float, float, float, float], dtheta: tuple[float, float, float]
) -> tuple[float, float, float, float]:
    """exp(dtheta) * q: apply a small rotation expressed in NED to an attitude."""
    ax, ay, az = dtheta
    angle = math.sqrt(ax * ax + ay * ay + az * az)
    if angle > 1e-9:
        s = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    else:
        s, c = 0.5, 1.0
    w, x, y, z = q
    return unit_product(c, ax * s, ay * s, az * s, w, x, y, z)  # exp(dtheta) * q: NED frame


def unit_product(
    aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float, bz: float
) -> tuple[float, float, float, float]:
    """The Hamilton product a * b, normalised, scalar part made non-negative."""
    qw = aw * bw - ax * bx - ay * by - az * bz
    qx = aw * bx + ax * bw + ay * bz - az * by
    qy = aw * by - ax * bz + ay * bw + az * bx
    qz = aw * bz + ax * by - ay * bx + az * bw
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    if qw < 0.0:
        inv = -inv
    return (qw * inv, qx * inv, qy * inv, qz * inv)


class ErrorStateEkf:
    """Nominal state as floats, covariance as a 17x17 numpy array; no time handling here."""

    def __init__(self, params: NavParams, gravity_m_s2: float) -> None:
        self.params = params
        self.g = gravity_m_s2
        self.p: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.v: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
        self.bg: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.ba: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self.wind: tuple[float, float] = (0.0, 0.0)
        self.P: Matrix = np.zeros((N_STATES, N_STATES))
        # Deltas summed since the last covariance step.
        self._cov_dt = 0.0
        self._cov_dv = [0.0, 0.0, 0.0]
        self._cov_steps = 0
        self._cov_every = params.cov_every
        self._imu_dt = params.imu_period_ns / 1e9
        self._q_T = math.nan  # the step length of _q_diag (none yet)
        self._q_diag: Matrix = np.zeros(N_STATES)
        # Corrections since the output predictor last took them (summed: first order).
        self.pending: Matrix = np.zeros(N_STATES)
        self.dx: Matrix = np.zeros(N_STATES)  # the last measurement update's correction
        self._corrected = False
        # numba (0.4 s to import, compiled code loaded from its cache) only where a filter runs.
        from air_sitl.nav import kernels

        kernels.warm()
        self.kernels = kernels

    def init_covariance(self) -> None:
        p = self.params
        d = [p.init_pos_m**2] * 3 + [p.init_vel_m_s**2] * 3
        d += [p.init_tilt_rad**2, p.init_tilt_rad**2, p.init_yaw_rad**2]
        d += [p.init_gyro_bias_rad_s**2] * 3 + [p.init_accel_bias_m_s2**2] * 3
        d += [p.init_wind_m_s**2] * 2
        self.P = np.diag(np.array(d, dtype=np.float64))

    def predict(
        self, dang: tuple[float, float, float], dvel: tuple[float, float, float], dt: float
    ) -> None:
        """Advance the nominal state by one summed IMU delta; the covariance every few."""
        bg, ba = self.bg, self.ba
        dang = (dang[0] - bg[0] * dt, dang[1] - bg[1] * dt, dang[2] - bg[2] * dt)
        dvel = (dvel[0] - ba[0] * dt, dvel[1] - ba[1] * dt, dvel[2] - ba[2] * dt)
        self.p, self.v, self.q, dv_nav = integrate(self.p, self.v, self.q, dang, dvel, dt, self.g)
        c = self._cov_dv
        c[0] += dv_nav[0]
        c[1] += dv_nav[1]
        c[2] += dv_nav[2]
        self._cov_dt += dt
        self._cov_steps += 1
        if self._cov_steps >= self._cov_every:
            self._predict_covariance()

    def _predict_covariance(self) -> None:
        T = self._cov_dt
        dvx, dvy, dvz = self._cov_dv
        self.kernels.predict_covariance(
            self.P, rotation_matrix(self.q), T, dvx, dvy, dvz, self._process_noise(T)
        )
        self._cov_dt = 0.0
        self._cov_dv = [0.0, 0.0, 0.0]
        self._cov_steps = 0

    def _process_noise(self, T: float) -> Matrix:
        """The diagonal of Q over a covariance step of ``T`` s (kept: T repeats)."""
        if self._q_T != T:
            p = self.params
            qv = p.accel_noise_m_s2**2 * self._imu_dt * T
            qa = p.gyro_noise_rad_s**2 * self._imu_dt * T
            qbg = p.gyro_bias_noise_rad_s2**2 * T
            qba = p.accel_bias_noise_m_s3**2 * T
            qw = p.wind_noise_m_s2**2 * T
            q = (0, 0, 0, qv, qv, qv, qa, qa, qa, qbg, qbg, qbg, qba, qba, qba, qw, qw)
            self._q_diag = np.array(q, dtype=np.float64)
            self._q_T = T
        return self._q_diag

    def correct(self, dx: list[float]) -> None:
        """Inject an error-state correction into the nominal state and the pending sum."""
        pending = self.pending
        for i, d in enumerate(dx):
            pending[i] += d
        self.inject(dx)

    def inject(self, dx: list[float]) -> None:
        """Inject a correction into the nominal state (a measurement update has already
        added it to ``pending``)."""
        self._corrected = True
        p, v, bg, ba, w = self.p, self.v, self.bg, self.ba, self.wind
        self.p = (p[0] + dx[0], p[1] + dx[1], p[2] + dx[2])
        self.v = (v[0] + dx[3], v[1] + dx[4], v[2] + dx[5])
        self.q = rotate_global(self.q, (dx[6], dx[7], dx[8]))
        self.bg = (bg[0] + dx[9], bg[1] + dx[10], bg[2] + dx[11])
        self.ba = (ba[0] + dx[12], ba[1] + dx[13], ba[2] + dx[14])
        self.wind = (w[0] + dx[15], w[1] + dx[16])

    def take_pending(self) -> list[float] | None:
        """The corrections summed since the last call (None if they sum to nothing); the sum
        starts afresh."""
        if not self._corrected:
            return None
        self._corrected = False
        dx = self.pending.tolist()
        self.pending.fill(0.0)
        return dx if any(dx) else None

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
        self.q = rotate_global(self.q, (0.0, 0.0, delta))
        self.pending[ATT + 2] += delta
        self._corrected = True
        self.P[ATT + 2, :] = 0.0
        self.P[:, ATT + 2] = 0.0
        self.P[ATT + 2, ATT + 2] = variance
        return delta
