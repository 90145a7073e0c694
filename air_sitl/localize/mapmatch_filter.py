"""The horizontal filter under ``mapmatch`` (its prior) and ``fused`` (its output).

State: east, north (metres from home) and a velocity offset (east, north, m/s) added to the
dead-reckoned air velocity ``airspeed x AHRS heading``: the wind, plus the airspeed and heading
errors, learnt from the map fixes. Prediction integrates the dead-reckoned velocity between
frames; an update fuses one fix (a position with a 2x2 covariance) after a Mahalanobis gate.
Pure numpy, no I/O.
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


class PositionFilter:
    """Kalman filter on (east, north, offset east, offset north)."""

    def __init__(
        self,
        *,
        position_noise_m2_s: float = POSITION_NOISE_M2_S,
        offset_noise_m2_s3: float = OFFSET_NOISE_M2_S3,
    ) -> None:
        self.q_pos = position_noise_m2_s
        self.q_off = offset_noise_m2_s3
        self.x: Mat = np.zeros(4)
        self.p: Mat = np.eye(4)
        self.initialised = False

    def start(
        self, east_m: float, north_m: float, sigma_m: float, offset_sigma_m_s: float = 2.0
    ) -> None:
        """Start (or restart) at a position; the velocity offset is kept when restarting."""
        off = self.x[2:].copy() if self.initialised else np.zeros(2)
        self.x = np.array([east_m, north_m, off[0], off[1]])
        self.p = np.diag([sigma_m**2, sigma_m**2, offset_sigma_m_s**2, offset_sigma_m_s**2])
        self.initialised = True

    def predict(self, dt_s: float, v_air_en: tuple[float, float]) -> None:
        """Move on by ``dt_s`` at the dead-reckoned velocity plus the offset."""
        if not self.initialised or dt_s <= 0:
            return
        x, p = self.x, self.p
        x[0] += (v_air_en[0] + x[2]) * dt_s
        x[1] += (v_air_en[1] + x[3]) * dt_s
        f = np.eye(4)
        f[0, 2] = f[1, 3] = dt_s
        q = np.diag([self.q_pos * dt_s, self.q_pos * dt_s, self.q_off * dt_s, self.q_off * dt_s])
        self.p = f @ p @ f.T + q

    @property
    def position(self) -> tuple[float, float]:
        """(east, north) metres."""
        return (float(self.x[0]), float(self.x[1]))

    @property
    def sigma_m(self) -> float:
        """1-sigma of the position along its worst axis."""
        return math.sqrt(max(float(np.linalg.eigvalsh(self.p[:2, :2])[-1]), 0.0))

    def innovation_d2(self, east_m: float, north_m: float, sigma_m: float) -> float:
        """Squared Mahalanobis distance of a fix from the prediction."""
        y = np.array([east_m, north_m]) - self.x[:2]
        s = self.p[:2, :2] + np.eye(2) * sigma_m**2
        return float(y @ np.linalg.solve(s, y))

    def update(self, east_m: float, north_m: float, sigma_m: float, gate_d2: float | None) -> bool:
        """Fuse a fix unless its innovation exceeds ``gate_d2``; True when fused."""
        if not self.initialised:
            self.start(east_m, north_m, sigma_m)
            return True
        if gate_d2 is not None and self.innovation_d2(east_m, north_m, sigma_m) > gate_d2:
            return False
        h = np.zeros((2, 4))
        h[0, 0] = h[1, 1] = 1.0
        y = np.array([east_m, north_m]) - self.x[:2]
        s = self.p[:2, :2] + np.eye(2) * sigma_m**2
        k = self.p @ h.T @ np.linalg.inv(s)
        self.x = self.x + k @ y
        self.p = (np.eye(4) - k @ h) @ self.p
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
