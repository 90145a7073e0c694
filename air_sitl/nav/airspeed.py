"""Airspeed control (EKF2 airspeed_fusion, sideslip_fusion): true airspeed and wind.

Start: when flying (airspeed above ``airspeed_min_m_s``) with a valid velocity, the wind is
reset to ground velocity minus airspeed along the heading (EKF2 resetWindUsingAirspeed).
Fuse: true airspeed |v - wind| and, for a fixed wing, a synthetic zero sideslip; together
they bound the velocity through heading and wind when GNSS is gone, and they make the wind
observable while GNSS is there (the models: :func:`air_sitl.nav.kernels.airspeed_model`,
:func:`air_sitl.nav.kernels.sideslip_model`).
"""

from __future__ import annotations

import math

from air_sitl.nav.ekf import VEL, WIND, ErrorStateEkf
from air_sitl.nav.fusion import NO_MODEL, result
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
                r = ekf.rotation()
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
            k = ekf.kernels
            outcome = k.fuse_model(
                ekf.P, ekf.x, k.AIRSPEED, tas, p.airspeed_noise_m_s**2, p.airspeed_gate, ekf.dx,
                ekf.pending,
            )  # fmt: skip
            if outcome[1] == NO_MODEL:  # below 1 m/s of air: no direction to measure along
                self.counters.reject("model")
                continue
            res = result(ekf, outcome)
            self.tas_ratio = res.test_ratio
            if self.counters.gated(res):
                self.last_fused_ns = t_m
            if p.fuse_beta:
                self._fuse_beta(ekf)

    def _fuse_beta(self, ekf: ErrorStateEkf) -> None:
        """Synthetic sideslip: the air velocity has no body-y component (beta = 0)."""
        p = self.params
        k = ekf.kernels
        outcome = k.fuse_model(
            ekf.P, ekf.x, k.SIDESLIP, 0.0, p.beta_noise_rad**2, p.beta_gate, ekf.dx, ekf.pending
        )
        if outcome[1] != NO_MODEL:  # the air comes from ahead
            self.beta_ratio = result(ekf, outcome).test_ratio
