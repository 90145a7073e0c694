"""Counters and status of the filter: per-source counters, flags, test ratios.

:class:`NavStatus` is the future ``"nav"`` block of summary.json (horizontal error statistics
against truth are computed outside, by whoever has the truth) and carries what MAVLink
ESTIMATOR_STATUS reports (flags, test ratios, accuracies).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, TypeVar

from air_sitl.nav.buffer import TimedBuffer
from air_sitl.nav.fusion import FusionResult
from air_sitl.nav.params import NavParams
from air_sitl.state import NavFlags

T = TypeVar("T")


@dataclass(slots=True)
class SourceCounters:
    """Mutable counters of one aiding source (owned by its control module)."""

    received: int = 0
    fused: int = 0
    rejected: int = 0
    empty: int = 0
    resets: int = 0
    reasons: dict[str, int] = field(default_factory=dict)
    test_ratio: float = 0.0  # of the last gated measurement

    def reject(self, reason: str) -> None:
        self.rejected += 1
        self.reasons[reason] = self.reasons.get(reason, 0) + 1

    def admit(
        self, buffer: TimedBuffer[T], t_ns: int, item: T, valid: bool, window: tuple[int, int]
    ) -> bool:
        """Count one received measurement taken at ``t_ns`` and buffer it; False, counted by
        reason, when it is not ``valid``, outside ``window`` (the delayed horizon's start, the
        arrival time) or the buffer refuses it (full, out of order)."""
        self.received += 1
        if not valid:
            self.reject("invalid")
            return False
        if not window[0] <= t_ns <= window[1]:
            self.reject("time")
            return False
        if not buffer.push(t_ns, item):
            self.reject("rate")
            return False
        return True

    def gated(self, result: FusionResult) -> bool:
        """Count one gated update (fused, or rejected by the gate) and keep its test ratio;
        True when it fused."""
        self.test_ratio = result.test_ratio
        if result.fused:
            self.fused += 1
        else:
            self.reject("gate")
        return result.fused


class ScalarSource:
    """A sensor giving one number a reading (barometer, airspeed, compass): its counters and
    the readings waiting for the delayed horizon."""

    def __init__(self, params: NavParams) -> None:
        self.params = params
        self.counters = SourceCounters()
        self.buffer: TimedBuffer[float] = TimedBuffer(64)

    def admit(
        self, t_ns: int, value: float, valid: bool, now_ns: int, horizon_start_ns: int
    ) -> bool:
        """Count one reading taken at ``t_ns`` and buffer it (:meth:`SourceCounters.admit`,
        the window from the horizon's start to the arrival ``now_ns``)."""
        window = (horizon_start_ns, now_ns)
        return self.counters.admit(self.buffer, t_ns, value, valid, window)


@dataclass(frozen=True, slots=True, kw_only=True)
class AidStatus:
    """Counters of one source: received = fused + rejected + empty + still buffered."""

    name: str
    received: int
    fused: int
    rejected: int
    empty: int
    resets: int
    rejected_by_reason: dict[str, int]
    fusing: bool
    test_ratio: float

    @classmethod
    def of(cls, name: str, c: SourceCounters, *, fusing: bool) -> AidStatus:
        return cls(
            name=name,
            received=c.received,
            fused=c.fused,
            rejected=c.rejected,
            empty=c.empty,
            resets=c.resets,
            rejected_by_reason=dict(sorted(c.reasons.items())),
            fusing=fusing,
            test_ratio=c.test_ratio,
        )

    def to_json(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "received": self.received,
            "fused": self.fused,
            "rejected": self.rejected,
            "empty": self.empty,
            "resets": self.resets,
            "rejected_by_reason": self.rejected_by_reason,
        }


@dataclass(frozen=True, slots=True, kw_only=True)
class NavStatus:
    """Filter status at one instant (ESTIMATOR_STATUS fields plus our counters)."""

    sim_time_ns: int
    source: str  # horizontal position source now: "gnss", "aid:<name>", "dead_reckoning", "none"
    gnss_denied_s: float  # simulated time without GNSS fusion since GNSS first started
    flags: NavFlags
    gnss: AidStatus
    baro: AidStatus
    airspeed: AidStatus
    heading: AidStatus
    aids: tuple[AidStatus, ...]
    # Test ratios of the last update of each kind (ESTIMATOR_STATUS *_ratio).
    vel_ratio: float
    pos_horiz_ratio: float
    pos_vert_ratio: float
    mag_ratio: float
    tas_ratio: float
    beta_ratio: float
    pos_horiz_accuracy_m: float
    pos_vert_accuracy_m: float

    def to_json(self) -> dict[str, Any]:
        """The summary.json ``nav`` block (without the truth-based error statistics)."""
        return {
            "source": self.source,
            "gnss_denied_s": round(self.gnss_denied_s, 3),
            "gnss": self.gnss.to_json(),
            "aid": [a.to_json() for a in self.aids],
            "flags": {f.name: getattr(self.flags, f.name) for f in fields(self.flags)},
        }
