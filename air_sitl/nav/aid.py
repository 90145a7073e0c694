"""External position aid control (EKF2 ev_pos_control / aux global position), one per name.

Arrival (:meth:`AidControl.push`, at the caller's *now*): a measurement without a position is
empty; NaN/inf, a bad covariance, an unknown frame, a stamp in the future or behind the fusion
horizon, or one closer than ``aid_min_interval_ns`` to the previous accepted one (a flood) is
rejected and counted, as is one older than the previous accepted one (out of order).
Accepted ones wait in a buffer for the delayed horizon.

Fusion (at the measurement's own time): horizontal position, a 2-D update with a chi-square
gate. Start: a first measurement when no other horizontal position source exists resets the
position to it. Reset: an aid that is the only horizontal position source and has been
rejected continuously for ``aid_reset_timeout_ns`` resets the position to itself (EKF2's
reset on rejection timeout: a consistent aid wins against a drifted estimate, a short burst
of outliers does not). Stop: no accepted measurement for ``aid_timeout_ns``: the aid is lost.
"""

from __future__ import annotations

import math
from numbers import Integral, Real

import numpy as np

from air_sitl.frames import LocalNed
from air_sitl.nav.buffer import TimedBuffer
from air_sitl.nav.ekf import POS, ErrorStateEkf
from air_sitl.nav.fusion import result
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import SourceCounters
from air_sitl.nav.types import AidFrame, AidMeasurement, AidResult
from air_sitl.state import GeoPoint

# north, east, var_nn, cov_ne, var_ee
AidItem = tuple[float, float, float, float, float]


def _finite(values: object, n: int) -> tuple[float, ...] | None:
    """``values`` (any nesting: a 3x3 list or array is 9 values) as n finite floats, or None
    (wrong type, length, NaN, inf)."""
    try:
        arr = np.asarray(values, dtype=np.float64).ravel()
    except (TypeError, ValueError, OverflowError):
        return None
    if arr.size != n or not bool(np.isfinite(arr).all()):
        return None
    return tuple(arr.tolist())


def _is_empty(position: object) -> bool:
    """No position: None, or every coordinate None or NaN ("no estimate for this frame")."""
    if position is None:
        return True
    if isinstance(position, str | bytes):
        return False
    try:
        values = list(position)  # type: ignore[call-overload]
    except TypeError:
        return False
    return bool(values) and all(
        v is None or (isinstance(v, float | np.floating) and math.isnan(v)) for v in values
    )


class AidControl:
    def __init__(self, name: str, params: NavParams, home: GeoPoint) -> None:
        self.name = name
        self.params = params
        self.home = home
        self._local = LocalNed(home.lat_deg, home.lon_deg, home.alt_amsl_m)
        self.counters = SourceCounters()
        self.buffer: TimedBuffer[AidItem] = TimedBuffer(params.aid_buffer_len)
        self.last_accepted_ns: int | None = None  # measurement time
        self.last_arrival_ns: int | None = None  # caller's now at the last accepted one
        self.last_fused_ns: int | None = None
        self.first_reject_ns: int | None = None

    def alive(self, now_ns: int) -> bool:
        """An accepted measurement arrived within ``aid_timeout_ns`` (else the aid is lost)."""
        last = self.last_arrival_ns
        return last is not None and now_ns - last <= self.params.aid_timeout_ns

    def fusing(self, t_ns: int) -> bool:
        """Fused within the timeout at delayed time ``t_ns``."""
        last = self.last_fused_ns
        return last is not None and t_ns - last <= self.params.aid_timeout_ns

    def push(self, m: AidMeasurement, now_ns: int, horizon_start_ns: int) -> AidResult:
        c = self.counters
        c.received += 1
        if _is_empty(m.position):
            c.empty += 1
            return AidResult.EMPTY
        try:
            frame = AidFrame(m.frame)
        except (ValueError, TypeError):
            c.reject(AidResult.REJECTED_FRAME.value)
            return AidResult.REJECTED_FRAME
        item = self._parse(m, frame)
        stamp = m.sim_time_ns
        if item is None or isinstance(stamp, bool) or not isinstance(stamp, Integral):
            c.reject(AidResult.REJECTED_INVALID.value)
            return AidResult.REJECTED_INVALID
        t = int(stamp)
        if t > now_ns:
            c.reject(AidResult.REJECTED_FUTURE.value)
            return AidResult.REJECTED_FUTURE
        if t < horizon_start_ns:
            c.reject(AidResult.REJECTED_STALE.value)
            return AidResult.REJECTED_STALE
        last = self.last_accepted_ns
        if last is not None and t < last:
            c.reject(AidResult.REJECTED_ORDER.value)
            return AidResult.REJECTED_ORDER
        if last is not None and t - last < self.params.aid_min_interval_ns:
            c.reject(AidResult.REJECTED_RATE.value)
            return AidResult.REJECTED_RATE
        if not self.buffer.push(t, item):
            c.reject(AidResult.REJECTED_RATE.value)
            return AidResult.REJECTED_RATE
        self.last_accepted_ns = t
        self.last_arrival_ns = now_ns
        return AidResult.ACCEPTED

    def _parse(self, m: AidMeasurement, frame: AidFrame) -> AidItem | None:
        """North, east and the horizontal NED covariance, or None when anything is invalid."""
        pos = _finite(m.position, 3)
        if pos is None:
            return None
        if frame is AidFrame.ENU:
            north, east = pos[1], pos[0]
        elif frame is AidFrame.NED:
            north, east = pos[0], pos[1]
        else:
            if abs(pos[0]) > 90.0 or abs(pos[1]) > 180.0:
                return None
            north, east, _ = self._local.from_geodetic(pos[0], pos[1], pos[2])
        floor = self.params.aid_noise_floor_m**2
        if m.cov_m2 is not None:
            cov = _finite(m.cov_m2, 9)
            if cov is None:
                return None
            if frame is AidFrame.NED:
                vnn, vne, vee = cov[0], 0.5 * (cov[1] + cov[3]), cov[4]
            else:  # ENU axes (WGS84 covariances are given as east, north, up metres too)
                vee, vne, vnn = cov[0], 0.5 * (cov[1] + cov[3]), cov[4]
            if not (vnn > 0.0 and vee > 0.0 and vnn * vee - vne * vne > 0.0):
                return None
            vnn, vee = max(vnn, floor), max(vee, floor)
        else:
            sigma = self.params.aid_sigma_m if m.sigma_m is None else m.sigma_m
            if isinstance(sigma, bool) or not isinstance(sigma, Real):
                return None
            sigma = float(sigma)
            if not (math.isfinite(sigma) and sigma > 0.0):
                return None
            vnn = vee = max(sigma * sigma, floor)
            vne = 0.0
        return (north, east, vnn, vne, vee)

    def fuse_due(self, ekf: ErrorStateEkf, t_ns: int, only_source: bool, pos_valid: bool) -> bool:
        """Fuse what the horizon reached; True when the position was reset to this aid."""
        p = self.params
        reset = False
        for t_m, (n, e, vnn, vne, vee) in self.buffer.pop_due(t_ns):
            c = self.counters
            first = self.first_reject_ns
            timed_out = first is not None and t_m - first >= p.aid_reset_timeout_ns
            if not pos_valid or (only_source and timed_out):
                ekf.reset_states(POS, (n, e), max(vnn, vee))
                if pos_valid:
                    c.resets += 1
                pos_valid = reset = True
                self.first_reject_ns = None
                c.fused += 1
                self.last_fused_ns = t_m
                continue
            lag = (t_ns - t_m) * 1e-9
            res = result(
                ekf,
                ekf.kernels.fuse_position(
                    ekf.P, ekf.x, n, e, lag, vnn, vne, vee, p.aid_gate, ekf.dx, ekf.pending
                ),
            )
            if c.gated(res):
                self.last_fused_ns = t_m
                self.first_reject_ns = None
            elif first is None:
                self.first_reject_ns = t_m
        return reset

    def lost(self) -> None:
        """Forget a rejection run when the aid goes silent (a new run starts from scratch)."""
        self.first_reject_ns = None
