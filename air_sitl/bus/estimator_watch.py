"""Say when the estimators a flight relies on are not there, and what the log refused.

A flight with ``--wait-for``, ``--svo-columns`` or ``--nav-aid NAME`` expects estimates; a bus
that routes nothing (a wrong topology, a wrong endpoint, an estimator that never started)
would otherwise end with ``"estimates": {}`` and exit 0 in silence. :class:`EstimatorWatch`
warns once per name during the flight, :data:`SILENCE_WARN_S` wall seconds after the first
frame went out with no estimate from it; :func:`estimate_summary` and
:func:`estimate_warnings` give the end-of-flight account (summary.json and stderr).
"""

from __future__ import annotations

import threading
import time
from typing import IO, Any

from air_sitl.bus.estimates import EstimateLog

SILENCE_WARN_S = 5.0  # wall seconds after the first frame without a word from an estimator
_POLL_S = 0.25
TOPOLOGY_HINT = (
    "is it running, on this bus and vehicle? (through a router: see docs/bus-topologies.md)"
)


class EstimatorWatch:
    """A daemon thread that warns on ``stream`` about expected estimators still silent."""

    def __init__(self, log: EstimateLog, expected: tuple[str, ...], stream: IO[str]) -> None:
        self._log = log
        self._expected = expected
        self._stream = stream
        self._stop = threading.Event()
        self.warned: list[str] = []
        self._thread = threading.Thread(target=self._run, name="estimator-watch", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(_POLL_S):
            first = self._log.ledger.first_publish_wall_s
            if first is None or time.monotonic() - first < SILENCE_WARN_S:
                continue
            heard = set(self._log.names())
            for name in self._expected:
                if name not in heard and name not in self.warned:
                    self.warned.append(name)
                    self._stream.write(
                        f"air-sitl: warning: no estimate from {name!r} on "
                        f"{self._log.keys.estimate(name)} {SILENCE_WARN_S:g} s after the "
                        f"first frame: {TOPOLOGY_HINT}\n"
                    )
                    self._stream.flush()
            if len(self.warned) == len(self._expected) or heard >= set(self._expected):
                return

    def stop(self) -> None:
        """Stop watching (idempotent)."""
        self._stop.set()
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(timeout=2.0)


def estimate_summary(log: EstimateLog, expected: tuple[str, ...]) -> dict[str, Any]:
    """summary.json's account of the estimates (the log is closed).

    ``estimates``: rows logged per name; ``estimates_rejected``: counts by reason;
    ``estimates_missing``: expected names never heard; ``frames_without_estimate``: per name
    heard or expected, the published frames it never answered.
    """
    names = log.names()
    out: dict[str, Any] = {"estimates": {n: log.rows(n) for n in names}}
    rejected = dict(log.rejected)
    if rejected:
        out["estimates_rejected"] = rejected
    missing = [n for n in expected if n not in names]
    if missing:
        out["estimates_missing"] = missing
    published = log.ledger.count
    if published:
        out["frames_without_estimate"] = {
            n: published - log.answered(n) for n in dict.fromkeys((*names, *expected))
        }
    return out


def estimate_warnings(summary: dict[str, Any], log: EstimateLog) -> list[str]:
    """One line per thing to tell the user at the end of the flight."""
    lines = []
    rejected: dict[str, int] = summary.get("estimates_rejected", {})
    if rejected:
        by_reason = ", ".join(f"{k} {v}" for k, v in sorted(rejected.items()))
        lines.append(
            f"{sum(rejected.values())} estimate(s) rejected ({by_reason}); first: {log.first_error}"
        )
    for name in summary.get("estimates_missing", []):
        lines.append(
            f"no estimate from {name!r} on {log.keys.estimate(name)} in the whole flight: "
            f"{TOPOLOGY_HINT}"
        )
    published = log.ledger.count
    for name, count in summary.get("frames_without_estimate", {}).items():
        if count and name in log.names():
            lines.append(f"{count} of {published} frames got no estimate from {name!r}")
    return lines
