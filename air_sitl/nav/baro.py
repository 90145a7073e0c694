"""Barometer control (EKF2 baro_height_control): the height reference.

Start: the first reading sets the height (minus an offset taken against GNSS when a fix is
there). Fuse: height above home = baro altitude - offset - home altitude, as a down position
in the tangent plane at home (which the Earth curves away from: d^2 / 2R, 2.7 m at 6 km, is
added; the model: :func:`air_sitl.nav.kernels.fuse_height`). The offset (turn-on error plus
slow drift) is tracked by a scalar Kalman filter against GNSS altitude while GNSS is fusing,
and frozen during denial (EKF2 estimates a baro bias the same way). Reset: after
``baro_reset_timeout_ns`` of continuous rejection the height jumps to the barometer.
"""

from __future__ import annotations

import math

from air_sitl.nav.ekf import POS, ErrorStateEkf
from air_sitl.nav.fusion import result
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import ScalarSource
from air_sitl.nav.types import BaroSample

CURVATURE_1_M = 0.5 / 6_371_000.0  # 1 / (2 R), mean Earth radius (kernels.fuse_height too)


class BaroControl(ScalarSource):
    def __init__(self, params: NavParams, home_alt_m: float) -> None:
        super().__init__(params)
        self.home_alt_m = home_alt_m
        self.started = False
        self.offset_m = 0.0
        self.offset_var_m2 = 25.0
        self.last_alt_m: float | None = None
        self.last_fused_ns: int | None = None
        self.first_reject_ns: int | None = None
        self.ratio = 0.0

    def push(self, sample: BaroSample, now_ns: int, horizon_start_ns: int) -> bool:
        alt = sample.alt_amsl_m
        return self.admit(sample.sim_time_ns, alt, math.isfinite(alt), now_ns, horizon_start_ns)

    def fusing(self, t_ns: int) -> bool:
        last = self.last_fused_ns
        return last is not None and t_ns - last <= self.params.baro_timeout_ns

    def calibrate(self, gnss_alt_m: float, gnss_var_m2: float, dt_s: float) -> None:
        """One GNSS altitude observation of the offset (while GNSS fuses)."""
        if self.last_alt_m is None:
            return
        p = self.params
        self.offset_var_m2 += p.baro_bias_noise_m_sqrt_s**2 * dt_s
        z = self.last_alt_m - gnss_alt_m
        s = self.offset_var_m2 + gnss_var_m2 + p.baro_noise_m**2
        k = self.offset_var_m2 / s
        self.offset_m += k * (z - self.offset_m)
        self.offset_var_m2 *= 1.0 - k

    def _down_m(self, ekf: ErrorStateEkf, alt_m: float) -> float:
        """The tangent-plane down position of a baro altitude at the estimated horizontal
        position (the curvature term's Jacobian, below 1e-3, is left out)."""
        n, e = ekf.p[0], ekf.p[1]
        return -(alt_m - self.offset_m - self.home_alt_m) + (n * n + e * e) * CURVATURE_1_M

    def fuse_due(self, ekf: ErrorStateEkf, t_ns: int, gnss_alt_m: float | None) -> None:
        p = self.params
        for t_m, alt in self.buffer.pop_due(t_ns):
            self.last_alt_m = alt
            first = self.first_reject_ns
            if not self.started or (first is not None and t_m - first >= p.baro_reset_timeout_ns):
                if not self.started and gnss_alt_m is not None:
                    self.offset_m = alt - gnss_alt_m
                ekf.reset_states(POS + 2, (self._down_m(ekf, alt),), p.baro_noise_m**2)
                if self.started:
                    self.counters.resets += 1
                self.started = True
                self.first_reject_ns = None
                self.last_fused_ns = t_m
                self.counters.fused += 1
                continue
            lag = (t_ns - t_m) * 1e-9
            height = alt - self.offset_m - self.home_alt_m
            outcome = ekf.kernels.fuse_height(
                ekf.P, ekf.x, height, lag, p.baro_noise_m**2, p.baro_gate, ekf.dx, ekf.pending
            )
            r = result(ekf, outcome)
            self.ratio = r.test_ratio
            if self.counters.gated(r):
                self.last_fused_ns = t_m
                self.first_reject_ns = None
            elif first is None:
                self.first_reject_ns = t_m
