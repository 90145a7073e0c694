"""``fly --nav-aid NAME``: the estimates of ``estimate/NAME`` as the onboard filter's aid.

The :class:`~air_sitl.bus.estimates.EstimateLog` hands every estimate of NAME (on the zenoh
thread) to :class:`BusAidFeed`, which keeps it; the simulation thread takes them with
:meth:`BusAidFeed.take` and fuses them at their own time (the frame's exposure time). In
lockstep with the same name (``--wait-for NAME[:LAG]``) an estimate of frame k is taken only
once frame k + LAG has been handed to the camera, when lockstep guarantees it has arrived: the
run is then deterministic. Otherwise each estimate is taken at the first 50 Hz tick after it
arrived. An estimate the codec refuses is passed on as an invalid measurement (counted as
rejected by the filter); one without a position counts as empty.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import replace

from air_sitl.bus.codec import Estimate
from air_sitl.nav.types import AidFrame, AidMeasurement

_INVALID = ("invalid",)  # a position the filter refuses as invalid (a payload the codec refused)


class BusAidFeed:
    """Estimates of one estimator, waiting for the simulation thread."""

    def __init__(
        self,
        name: str,
        *,
        lockstep_lag: int | None = None,
        time_of: Callable[[int], int | None] | None = None,
    ) -> None:
        self.name = name
        self.lockstep_lag = lockstep_lag
        # The exposure time of a frame (an estimate naming only its frame may arrive before
        # the frame was published, when its time was not known yet).
        self.time_of = time_of
        self._lock = threading.Lock()
        self._pending: list[tuple[int, int, AidMeasurement]] = []  # (frame or -1, seq, m)
        self._seq = 0

    def on_estimate(
        self, name: str, frame: int | None, sim_time_ns: int | None, est: Estimate | None
    ) -> None:
        """An estimate of any estimator arrived (``est`` None: the codec refused it)."""
        if name != self.name:
            return
        if est is None:
            m = AidMeasurement(name=name, sim_time_ns=sim_time_ns, position=_INVALID)  # type: ignore[arg-type]
        elif est.enu_m is not None:
            m = AidMeasurement(
                name=name,
                sim_time_ns=sim_time_ns,  # type: ignore[arg-type]
                position=est.enu_m,
                frame=AidFrame.ENU.value,
                cov_m2=est.cov_enu_m2,
            )
        elif est.geo is not None:
            g = est.geo
            m = AidMeasurement(
                name=name,
                sim_time_ns=sim_time_ns,  # type: ignore[arg-type]
                position=(g.lat_deg, g.lon_deg, g.alt_amsl_m),
                frame=AidFrame.WGS84.value,
                cov_m2=est.cov_enu_m2,
            )
        else:
            m = AidMeasurement(name=name, sim_time_ns=sim_time_ns, position=None)  # type: ignore[arg-type]
        with self._lock:
            self._seq += 1
            self._pending.append((-1 if frame is None else frame, self._seq, m))

    def take(self, frames_submitted: int) -> list[AidMeasurement]:
        """What may be fused now, in frame order (``frames_submitted``: frames handed out)."""
        with self._lock:
            if not self._pending:
                return []
            lag = self.lockstep_lag
            if lag is None:
                ready, self._pending = self._pending, []
            else:
                limit = frames_submitted - 1 - lag
                ready = [p for p in self._pending if p[0] <= limit]
                self._pending = [p for p in self._pending if p[0] > limit]
        ready.sort(key=lambda p: (p[0], p[1]) if lag is not None else (0, p[1]))
        return [self._timed(frame, m) for frame, _, m in ready]

    def _timed(self, frame: int, m: AidMeasurement) -> AidMeasurement:
        if m.sim_time_ns is None and frame >= 0 and self.time_of is not None:
            t = self.time_of(frame)
            if t is not None:
                return replace(m, sim_time_ns=t)
        return m
