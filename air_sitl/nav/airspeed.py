"""Airspeed control (EKF2 airspeed_fusion, sideslip_fusion): true airspeed and wind.

Start: when flying (airspeed above ``airspeed_min_m_s``) with a valid velocity, the wind is
reset to ground velocity minus airspeed along the heading (EKF2 resetWindUsingAirspeed).
Fuse: true airspeed |v - wind| and, for a fixed wing, a synthetic zero sideslip; together
they bound the velocity through heading and wind when GNSS is gone, and they make the wind
observable while GNSS is there.
"""

from __future__ import annotations

import math

from air_sitl.nav.ekf import ATT, N_STATES, VEL, WIND, ErrorStateEkf, rotation_matrix
from air_sitl.nav.fusion import fuse_scalar
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import ScalarSource
from air_sitl.nav.types import AirspeedSample


class AirspeedControl(ScalarSource):
    def __init__(self, params: NavParams) -> None:
        super().__init__(params)
        self.wind_started = False
        self.last_fused_ns: int | None = None
        self.tas_ratio = 0.0
        self.beta_ratio = 0.0

    def push(self, sample: AirspeedSample, now_ns: int, horizon_start_ns: int) -> bool:
        tas = sample.airspeed_m_s
        valid = math.isfinite(tas) and tas >= 0.0
        return self.admit(sample.sim_time_ns, tas, valid, now_ns, horizon_start_ns)

    def fuse_due(self, ekf: ErrorStateEkf, t_ns: int, velocity_valid: bool) -> None:
        p = self.params
        for t_m, tas in self.buffer.pop_due(t_ns):
            if tas < p.airspeed_min_m_s:
                self.counters.empty += 1  # not flying: nothing to fuse
                continue
            if not self.wind_started:
                # Air velocity along the body x axis projected on the horizontal.
                r = rotation_matrix(ekf.q)
                hx, hy = r[0], r[3]
                norm = math.hypot(hx, hy) or 1.0
                air = (tas * hx / norm, tas * hy / norm)
                if velocity_valid:
                    wind = (ekf.v[0] - air[0], ekf.v[1] - air[1])
                    ekf.reset_states(WIND, wind, p.init_wind_m_s**2 * 0.25)
                else:  # no velocity source yet: assume calm air until one comes
                    ekf.reset_states(VEL, air, p.init_wind_m_s**2)
                    ekf.reset_states(WIND, (0.0, 0.0), p.init_wind_m_s**2)
                self.wind_started = True
            vn, ve, vd = ekf.v
            rn, re = vn - ekf.wind[0], ve - ekf.wind[1]
            pred = math.sqrt(rn * rn + re * re + vd * vd)
            if pred < 1.0:
                self.counters.reject("model")
                continue
            inv = 1.0 / pred
            h = [0.0] * N_STATES
            h[VEL], h[VEL + 1], h[VEL + 2] = rn * inv, re * inv, vd * inv
            h[WIND], h[WIND + 1] = -rn * inv, -re * inv
            res = fuse_scalar(ekf, h, tas - pred, p.airspeed_noise_m_s**2, p.airspeed_gate)
            self.tas_ratio = res.test_ratio
            if self.counters.gated(res):
                self.last_fused_ns = t_m
            if p.fuse_beta:
                self._fuse_beta(ekf)

    def _fuse_beta(self, ekf: ErrorStateEkf) -> None:
        """Synthetic sideslip: the air velocity has no body-y component (beta = 0)."""
        model = sideslip(ekf.q, ekf.v, ekf.wind)
        if model is None:
            return
        beta, h = model
        p = self.params
        res = fuse_scalar(ekf, h, -beta, p.beta_noise_rad**2, p.beta_gate)
        self.beta_ratio = res.test_ratio


def sideslip(
    q: tuple[float, float, float, float],
    v: tuple[float, float, float],
    wind: tuple[float, float],
) -> tuple[float, list[float]] | None:
    """Sideslip (body y / body x air velocity) and its Jacobian on the error state; None when
    the air does not come from ahead (below 1 m/s along the body x axis)."""
    r = rotation_matrix(q)
    vn, ve, vd = v
    a = (vn - wind[0], ve - wind[1], vd)
    # Body air velocity = R^T a; column i of R is body axis i in NED.
    c0 = (r[0], r[3], r[6])
    c1 = (r[1], r[4], r[7])
    bx = c0[0] * a[0] + c0[1] * a[1] + c0[2] * a[2]
    by = c1[0] * a[0] + c1[1] * a[1] + c1[2] * a[2]
    if bx < 1.0:
        return None
    beta = by / bx
    # d(body_i)/d(dtheta) = c_i x a (global attitude error); d/dv = c_i; d/dwind = -c_i;
    # d(beta) = d(by) / bx - by d(bx) / bx^2.
    x0 = (c0[1] * a[2] - c0[2] * a[1], c0[2] * a[0] - c0[0] * a[2], c0[0] * a[1] - c0[1] * a[0])
    x1 = (c1[1] * a[2] - c1[2] * a[1], c1[2] * a[0] - c1[0] * a[2], c1[0] * a[1] - c1[1] * a[0])
    inv = 1.0 / bx
    k = by * inv * inv
    h = [0.0] * N_STATES
    for i in range(3):
        h[VEL + i] = c1[i] * inv - c0[i] * k
        h[ATT + i] = x1[i] * inv - x0[i] * k
    h[WIND], h[WIND + 1] = -h[VEL], -h[VEL + 1]
    return beta, h
