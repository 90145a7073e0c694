"""Magnetic heading control (EKF2 mag heading fusion, EKF2_MAG_TYPE = heading).

Start: the first reading resets the yaw (tilt kept). Fuse: yaw = heading + declination,
the innovation wrapped to [-pi, pi] (the model: :func:`air_sitl.nav.kernels.heading_model`).
Reset: after 5 s of continuous rejection, yaw jumps to the compass (a filter that lost its
heading would otherwise never recover without GNSS).
"""

from __future__ import annotations

import math

from air_sitl.nav.ekf import ErrorStateEkf
from air_sitl.nav.fusion import NO_MODEL, result
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import ScalarSource
from air_sitl.nav.types import HeadingSample

RESET_TIMEOUT_NS = 5_000_000_000


class MagControl(ScalarSource):
    def __init__(self, params: NavParams) -> None:
        super().__init__(params)
        self.started = False
        self.first_reject_ns: int | None = None
        self.last_heading_rad: float | None = None  # newest arrival (alignment)
        self.ratio = 0.0

    def push(self, sample: HeadingSample, now_ns: int, horizon_start_ns: int) -> bool:
        heading = sample.heading_rad
        admitted = self.admit(
            sample.sim_time_ns, heading, math.isfinite(heading), now_ns, horizon_start_ns
        )
        if admitted:
            self.last_heading_rad = heading
        return admitted

    def fuse_due(self, ekf: ErrorStateEkf, t_ns: int) -> None:
        p = self.params
        for t_m, heading in self.buffer.pop_due(t_ns):
            yaw_meas = heading + p.mag_declination_rad
            first = self.first_reject_ns
            if not self.started or (first is not None and t_m - first >= RESET_TIMEOUT_NS):
                ekf.reset_yaw(yaw_meas, p.heading_noise_rad**2)
                if self.started:
                    self.counters.resets += 1
                self.started = True
                self.first_reject_ns = None
                self.counters.fused += 1
                continue
            k = ekf.kernels
            outcome = k.fuse_model(
                ekf.P, ekf.x, k.HEADING, yaw_meas, p.heading_noise_rad**2, p.heading_gate,
                ekf.dx, ekf.pending,
            )  # fmt: skip
            if outcome[1] == NO_MODEL:  # pointing straight up or down: heading undefined
                self.counters.empty += 1
                continue
            res = result(ekf, outcome)
            self.ratio = res.test_ratio
            if self.counters.gated(res):
                self.first_reject_ns = None
            elif self.first_reject_ns is None:
                self.first_reject_ns = t_m
