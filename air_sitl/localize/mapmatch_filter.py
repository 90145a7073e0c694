"""The horizontal filter under ``mapmatch`` (its prior) and ``fused`` (its output).

State: east, north (metres from home) and a velocity offset (east, north, m/s) added to the
dead-reckoned air velocity ``airspeed x AHRS heading``: the wind, plus the airspeed and heading
errors, learnt from the map fixes. Prediction integrates the dead-reckoned velocity between
frames; an update fuses one fix (a position with a 2x2 covariance) after a Mahalanobis gate.

With ``tilt=True`` (``fused``) two more states hold the AHRS tilt error in the body frame
(forward, right; radians). A map fix is the aircraft position seen through the AHRS attitude,
so a tilt error moves every fix by about ``height x tilt`` along the body axes: a bias that
turns with the heading. On a straight leg it cannot be told from a position error; each turn
separates them (the dead reckoning carries the position through the turn while the fix offset
turns with the aircraft). The state drifts as slowly as the AHRS attitude does
(:data:`TILT_DRIFT_RAD_SQRT_S`). Pure numpy, no I/O.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.frames import quat2euler
from air_sitl.localize.base import Observation
from air_sitl.state import Quat

Mat = npt.NDArray[np.float64]

POSITION_NOISE_M2_S = 0.25  # white velocity noise of dead reckoning (heading noise, gusts)
OFFSET_NOISE_M2_S3 = 0.004  # random walk of the wind / velocity offset
TILT_SIGMA_RAD = 0.008  # prior 1-sigma of the AHRS tilt error (mapmatch_core's floor)
TILT_DRIFT_RAD_SQRT_S = 0.0005  # random walk of the AHRS tilt error (a small MEMS AHRS)
CHI2_2DOF_999 = 13.82  # 99.9 % of a 2-D Gaussian innovation lies below this


def heading_rad(q: Quat) -> float:
    """AHRS heading (yaw), radians from north towards east."""
    return quat2euler(q)[2]


def air_velocity_en(obs: Observation, prev_q: Quat | None, speed_m_s: float) -> tuple[float, float]:
    """Mean dead-reckoned velocity (east, north) since the previous frame: the airspeed along
    the AHRS heading, averaged over the IMU samples of the interval (or the two frames')."""
    psis = [heading_rad(s.q_ahrs_body_to_ned_wxyz) for s in obs.imu]
    if not psis:
        now = heading_rad(obs.q_ahrs_body_to_ned_wxyz)
        prev = heading_rad(prev_q) if prev_q is not None else now
        psis = [prev + 0.5 * math.remainder(now - prev, math.tau)]
    ve = sum(math.sin(p) for p in psis) / len(psis)
    vn = sum(math.cos(p) for p in psis) / len(psis)
    return (speed_m_s * ve, speed_m_s * vn)


def tilt_jacobian(height_m: float, heading: float) -> Mat:
    """d(fix east, north) / d(tilt forward, right): the body axes on the ground, x height."""
    s, c = math.sin(heading), math.cos(heading)
    return height_m * np.array([[s, c], [c, -s]])


class PositionFilter:
    """Kalman filter on (east, north, offset east, offset north[, tilt forward, tilt right])."""

    def __init__(
        self,
        *,
        position_noise_m2_s: float = POSITION_NOISE_M2_S,
        offset_noise_m2_s3: float = OFFSET_NOISE_M2_S3,
        tilt: bool = False,
        tilt_sigma_rad: float = TILT_SIGMA_RAD,
        tilt_drift_rad_sqrt_s: float = TILT_DRIFT_RAD_SQRT_S,
    ) -> None:
        self.q_pos = position_noise_m2_s
        self.q_off = offset_noise_m2_s3
        self.tilt = tilt
        self.tilt_sigma_rad = tilt_sigma_rad
        self.q_tilt = tilt_drift_rad_sqrt_s**2
        self.n = 6 if tilt else 4
        self.x: Mat = np.zeros(self.n)
        self.p: Mat = np.eye(self.n)
        self.initialised = False

    def start(
        self, east_m: float, north_m: float, sigma_m: float, offset_sigma_m_s: float = 2.0
    ) -> None:
        """Start (or restart) at a position; the velocity offset and tilt are kept when
        restarting (with their uncertainty)."""
        if self.initialised:
            x, p = self.x.copy(), self.p.copy()
            x[:2] = (east_m, north_m)
            p[:2, :] = 0.0
            p[:, :2] = 0.0
            p[0, 0] = p[1, 1] = sigma_m**2
        else:
            x = np.zeros(self.n)
            x[:2] = (east_m, north_m)
            var = [sigma_m**2] * 2 + [offset_sigma_m_s**2] * 2 + [self.tilt_sigma_rad**2] * 2
            p = np.diag(var[: self.n])
        self.x, self.p = x, p
        self.initialised = True

    def predict(self, dt_s: float, v_air_en: tuple[float, float]) -> None:
        """Move on by ``dt_s`` at the dead-reckoned velocity plus the offset."""
        if not self.initialised or dt_s <= 0:
            return
        x, p = self.x, self.p
        x[0] += (v_air_en[0] + x[2]) * dt_s
        x[1] += (v_air_en[1] + x[3]) * dt_s
        # F = I + dt (position <- offset): F P F^T written out, without two matrix products.
        p[:2, :] += dt_s * p[2:4, :]
        p[:, :2] += dt_s * p[:, 2:4]
        q = (self.q_pos * dt_s, self.q_pos * dt_s, self.q_off * dt_s, self.q_off * dt_s)
        p[np.diag_indices(4)] += q
        if self.tilt:
            p[4, 4] += self.q_tilt * dt_s
            p[5, 5] += self.q_tilt * dt_s

    @property
    def position(self) -> tuple[float, float]:
        """(east, north) metres."""
        return (float(self.x[0]), float(self.x[1]))

    @property
    def sigma_m(self) -> float:
        """1-sigma of the position along its worst axis."""
        return math.sqrt(max(float(np.linalg.eigvalsh(self.p[:2, :2])[-1]), 0.0))

    def _h(self, height_m: float | None, heading: float | None) -> Mat:
        h = np.zeros((2, self.n))
        h[0, 0] = h[1, 1] = 1.0
        if self.tilt and height_m is not None and heading is not None:
            h[:, 4:6] = tilt_jacobian(height_m, heading)
        return h

    def expected_fix(
        self, height_m: float | None = None, heading: float | None = None
    ) -> tuple[float, float]:
        """Where a map fix should fall: the position plus the tilt's offset (when modelled)."""
        z = self._h(height_m, heading) @ self.x
        return (float(z[0]), float(z[1]))

    def innovation_d2(
        self,
        east_m: float,
        north_m: float,
        sigma_m: float,
        *,
        height_m: float | None = None,
        heading: float | None = None,
    ) -> float:
        """Squared Mahalanobis distance of a fix from the prediction."""
        h = self._h(height_m, heading)
        y = np.array([east_m, north_m]) - h @ self.x
        s = h @ self.p @ h.T + np.eye(2) * sigma_m**2
        return float(y @ np.linalg.solve(s, y))

    def update(
        self,
        east_m: float,
        north_m: float,
        sigma_m: float,
        gate_d2: float | None,
        *,
        height_m: float | None = None,
        heading: float | None = None,
    ) -> bool:
        """Fuse a fix unless its innovation exceeds ``gate_d2``; True when fused.

        With the tilt states, ``height_m`` and ``heading`` (AHRS yaw, radians) of the frame
        relate the fix to them; without those the fix is taken as the position itself (GNSS).
        """
        if not self.initialised:
            self.start(east_m, north_m, sigma_m)
            return True
        h = self._h(height_m, heading)
        y = np.array([east_m, north_m]) - h @ self.x
        ph = self.p @ h.T
        s = h @ ph + np.eye(2) * sigma_m**2
        if gate_d2 is not None and float(y @ np.linalg.solve(s, y)) > gate_d2:
            return False
        k = ph @ np.linalg.inv(s)
        self.x = self.x + k @ y
        self.p = self.p - k @ ph.T
        self.p = 0.5 * (self.p + self.p.T)
        return True

    def cov_enu(self, var_up_m2: float) -> tuple[float, ...]:
        """The 3x3 ENU covariance, row-major, with the given vertical variance."""
        p = self.p
        return (
            float(p[0, 0]), float(p[0, 1]), 0.0,
            float(p[1, 0]), float(p[1, 1]), 0.0,
            0.0, 0.0, var_up_m2,
        )  # fmt: skip
