"""What one bench run compares: scenarios, methods, external localizers, where results go.

Parsed once at the edge (``air-sitl bench`` options) into :class:`BenchConfig`; every later
step reads only this.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from air_sitl.localize.external import ExternalLocalizer
from air_sitl.sweep.entries import method_problem, parse_localizer, parse_methods

FLIGHT_DATE = 1  # the flight imagery's map date when one bench flies one date
FLIGHT_DATES = (0, 1, 2)  # what ``air-sitl bench`` flies by default: one bench per date gap
REFERENCE_DATE = 0  # what map-matching methods match against
__all__ = [
    "FLIGHT_DATE",
    "FLIGHT_DATES",
    "REFERENCE_DATE",
    "BenchConfig",
    "ExternalLocalizer",
    "method_problem",
    "parse_localizer",
    "parse_methods",
]


@dataclass(frozen=True, slots=True, kw_only=True)
class BenchConfig:
    """One bench: scenarios x (methods + external localizers), results under ``out``."""

    scenarios: tuple[str, ...]
    methods: tuple[str, ...]
    localizers: tuple[ExternalLocalizer, ...] = ()
    out: Path
    jobs: int = 1
    ray: str | None = None  # run on Ray: '' a local Ray, else the cluster's address
    missions: Path
    map: str | None = None  # every scenario's map (None: urban / forest by the plan name)
    flight_date: int = FLIGHT_DATE
    reference_date: int = REFERENCE_DATE
    align: str = "none"
    seed: int = 0
    # fly's --wait-timeout for the lockstep flights of external localizers (None: fly's default)
    wait_timeout_s: float | None = None
    quiet: bool = False

    @property
    def archives(self) -> Path:
        return self.out / "archives"

    @property
    def reports(self) -> Path:
        return self.out / "reports"

    @property
    def entries(self) -> tuple[str, ...]:
        """Every column of the leaderboard: built-in methods, then external localizers."""
        return (*self.methods, *(loc.name for loc in self.localizers))
