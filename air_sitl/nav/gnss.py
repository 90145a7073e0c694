"""GNSS control (EKF2 gps_control): when to start, fuse, reset and stop GNSS aiding.

Start: the first usable 3-D fix resets horizontal position and velocity. Fuse: horizontal
position (a 2-D gated update) and 3-D velocity. Reset: after ``gnss_reset_timeout_ns`` of
continuous rejection (position and velocity both failing), position and velocity jump to
GNSS. Stop: no fix for ``gnss_timeout_ns`` (denial, loss): the filter dead-reckons.
GNSS height is not fused: the barometer is the height reference and GNSS only calibrates it.
"""

from __future__ import annotations

import math

from air_sitl.frames import LocalNed
from air_sitl.nav.buffer import TimedBuffer
from air_sitl.nav.ekf import POS, VEL, ErrorStateEkf
from air_sitl.nav.fusion import result
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import SourceCounters
from air_sitl.state import GeoPoint, GpsFix

# n, e, d, vn, ve, vd, eph, epv, alt_amsl
GnssItem = tuple[float, float, float, float, float, float, float, float, float]


class GnssControl:
    def __init__(self, params: NavParams, home: GeoPoint) -> None:
        self.params = params
        self.home = home
        self._local = LocalNed(home.lat_deg, home.lon_deg, home.alt_amsl_m)
        self.counters = SourceCounters()
        self.buffer: TimedBuffer[GnssItem] = TimedBuffer(64)
        self.started = False
        self.last_fix_ns: int | None = None  # newest fix time fused or gated
        self.last_fused_ns: int | None = None
        self.first_reject_ns: int | None = None
        self.last_alt_amsl_m: float | None = None  # of the last fused fix (baro offset)
        self.last_epv_m = 0.0
        self.pos_ratio = 0.0
        self.vel_ratio = 0.0

    def push(self, fix: GpsFix, now_ns: int, horizon_start_ns: int) -> bool:
        """Validate and buffer one fix; False (counted) if unusable."""
        c = self.counters
        c.received += 1
        values = (fix.lat_deg, fix.lon_deg, fix.alt_amsl_m, *fix.vel_ned_m_s, fix.eph_m, fix.epv_m)
        if fix.fix_type < 3:
            c.empty += 1
            return False
        if not all(math.isfinite(x) for x in values) or abs(fix.lat_deg) > 90.0:
            c.reject("invalid")
            return False
        if fix.sim_time_ns > now_ns:
            c.reject("future")
            return False
        if fix.sim_time_ns < horizon_start_ns:
            c.reject("stale")
            return False
        n, e, d = self._local.from_geodetic(fix.lat_deg, fix.lon_deg, fix.alt_amsl_m)
        v = fix.vel_ned_m_s
        item = (n, e, d, v[0], v[1], v[2], fix.eph_m, fix.epv_m, fix.alt_amsl_m)
        if not self.buffer.push(fix.sim_time_ns, item):
            c.reject("rate")
            return False
        return True

    def fusing(self, t_ns: int) -> bool:
        """GNSS is an active horizontal source at delayed time ``t_ns``."""
        last = self.last_fused_ns
        return self.started and last is not None and t_ns - last <= self.params.gnss_timeout_ns

    def fuse_due(self, ekf: ErrorStateEkf, t_ns: int) -> None:
        p = self.params
        for t_m, it in self.buffer.pop_due(t_ns):
            n, e, _d, vn, ve, vd, eph, epv, alt = it
            pos_var = max(eph, p.gnss_pos_noise_m) ** 2
            vel_var = p.gnss_vel_noise_m_s**2
            self.last_fix_ns = t_m
            if not self.started or self._reset_due(t_m):
                ekf.reset_states(POS, (n, e), pos_var)
                ekf.reset_states(VEL, (vn, ve, vd), vel_var)
                if self.started:
                    self.counters.resets += 1
                self.started = True
                self.first_reject_ns = None
                self._fused(t_m, alt, epv)
                continue
            lag = (t_ns - t_m) * 1e-9
            k = ekf.kernels
            P, x, dx, pending = ekf.P, ekf.x, ekf.dx, ekf.pending
            pos = result(
                ekf,
                k.fuse_position(
                    P, x, n, e, lag, pos_var, 0.0, pos_var, p.gnss_pos_gate, dx, pending
                ),
            )
            vel = result(
                ekf, k.fuse_velocity(P, x, vn, ve, vd, vel_var, p.gnss_vel_gate, dx, pending)
            )
            self.pos_ratio, self.vel_ratio = pos.test_ratio, vel.test_ratio
            self.counters.test_ratio = pos.test_ratio
            if pos.fused or vel.fused:
                self.first_reject_ns = None
                self._fused(t_m, alt, epv)
            else:
                self.counters.reject("gate")
                if self.first_reject_ns is None:
                    self.first_reject_ns = t_m

    def _reset_due(self, t_m: int) -> bool:
        first = self.first_reject_ns
        return first is not None and t_m - first >= self.params.gnss_reset_timeout_ns

    def _fused(self, t_m: int, alt: float, epv: float) -> None:
        self.counters.fused += 1
        self.last_fused_ns = t_m
        self.last_alt_amsl_m = alt
        self.last_epv_m = epv
