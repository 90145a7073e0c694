"""The leaderboard: method x scenario figures from the eval reports, as JSON and markdown.

Figures per cell (SPEC section 5 names): median, p95 and rmse horizontal error, recall@5 m and
@25 m, availability, the fix rate and the longest time without a map fix (null for a method
without map fixes), drift % and the turn/straight RPE ratio. A method's summary row is the median
over the scenarios it was measured on; a failed or missing cell is ``null`` / "-" (never 0).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from air_sitl.maps.dates import date_name, gap_name
from air_sitl.sweep.measurements import EntryResult

# (leaderboard key, path into the SPEC report, markdown title, format, better)
FIGURES: tuple[tuple[str, tuple[str, ...], str, str, str], ...] = (
    ("median_m", ("horizontal_error_m", "median"), "median horizontal error (m)", ".1f", "low"),
    ("p95_m", ("horizontal_error_m", "p95"), "p95 horizontal error (m)", ".1f", "low"),
    ("rmse_m", ("horizontal_error_m", "rmse"), "horizontal RMSE (m)", ".1f", "low"),
    # 5 m: what separates localizers that all stay within AIR's 25 m across the date gaps
    ("recall_5m", ("recall", "5m"), "recall@5 m (share of all frames)", ".3f", "high"),
    ("recall_25m", ("recall", "25m"), "recall@25 m (share of all frames)", ".3f", "high"),
    ("availability", ("availability",), "availability", ".3f", "high"),
    # Availability stays 1 while a map-based method propagates between fixes: the fix rate
    # says how many frames the map really gave (SPEC section 10).
    (
        "fix_rate",
        ("fix_rate",),
        "fix rate (share of all frames with an accepted map fix)",
        ".3f",
        "high",
    ),
    (
        "longest_without_fix_s",
        ("longest_without_fix_s",),
        "longest time without a map fix (s)",
        ".1f",
        "low",
    ),
    ("drift_pct", ("drift_pct",), "final drift (% of distance)", ".2f", "low"),
    (
        "turn_straight_rpe_ratio",
        ("turn_straight_rpe_ratio",),
        "turn / straight RPE@100 m",
        ".2f",
        "low",
    ),
)
SCENARIO_CLASSES = {
    "UL": "urban line",
    "UR": "urban rectangle",
    "UC": "urban circle",
    "FL": "forest line",
    "FR": "forest rectangle",
    "FC": "forest circle",
    "AL": "farmland line",
    "AR": "farmland rectangle",
    "AC": "farmland circle",
}


def _get(report: dict[str, Any] | None, path: tuple[str, ...]) -> float | None:
    value: Any = report
    for key in path:
        if not isinstance(value, dict):
            return None
        value = value.get(key)
    if value is None or not isinstance(value, int | float) or not math.isfinite(value):
        return None
    return float(value)


@dataclass(frozen=True, slots=True, kw_only=True)
class Leaderboard:
    """Every cell, and the order to show them in."""

    entries: tuple[str, ...]
    scenarios: tuple[str, ...]
    cells: dict[tuple[str, str], EntryResult]
    reference_date: int | None = None  # the map date map-based methods match against
    flight_date: int | None = None  # the map date the flights' camera saw
    map_dates: tuple[str | None, ...] = ()  # the acquisition date of each map date index

    def figure(self, entry: str, scenario: str, key: str) -> float | None:
        result = self.cells.get((entry, scenario))
        path = next(p for k, p, *_ in FIGURES if k == key)
        return None if result is None else _get(result.report, path)

    def summary(self, entry: str, key: str) -> float | None:
        values = [self.figure(entry, s, key) for s in self.scenarios]
        known = [v for v in values if v is not None]
        return statistics.median(known) if known else None

    def to_json(self) -> dict[str, Any]:
        rows = []
        for entry in self.entries:
            for scenario in self.scenarios:
                result = self.cells.get((entry, scenario))
                row: dict[str, Any] = {"method": entry, "scenario": scenario}
                for key, *_ in FIGURES:
                    row[key] = self.figure(entry, scenario, key)
                row["frames_per_s"] = None if result is None else result.frames_per_s
                row["error"] = "not run" if result is None else result.error
                rows.append(row)
        summary = {
            entry: {key: self.summary(entry, key) for key, *_ in FIGURES} for entry in self.entries
        }
        return {
            "v": 1,
            "methods": list(self.entries),
            "scenarios": list(self.scenarios),
            "reference_date": self.reference_date,
            "flight_date": self.flight_date,
            "map_dates": list(self.map_dates),
            "rows": rows,
            "summary": summary,
        }

    @property
    def gap(self) -> str:
        """``reference date 0 (2009-06-20) -> flight date 2 (2016-04-22)``."""
        return gap_name(self.reference_date, self.flight_date, self.map_dates)

    def to_markdown(self) -> str:
        lines = ["# Leaderboard", ""]
        lines.append(
            f"{len(self.entries)} methods x {len(self.scenarios)} scenarios; each cell from "
            "`air-sitl eval` (SPEC section 5); the last column is the median over scenarios."
        )
        if self.flight_date is not None:
            lines.append(
                f"Map dates: {self.gap} (map-based methods match the reference map while "
                "the camera sees the flight's date)."
            )
        for key, _path, title, fmt, better in FIGURES:
            lines += ["", f"## {title} ({'lower' if better == 'low' else 'higher'} is better)", ""]
            lines.append("| method | " + " | ".join(self.scenarios) + " | median |")
            lines.append("|---" * (len(self.scenarios) + 2) + "|")
            for entry in self.entries:
                cells = [_fmt(self.figure(entry, s, key), fmt) for s in self.scenarios]
                lines.append(
                    f"| {entry} | "
                    + " | ".join(cells)
                    + f" | {_fmt(self.summary(entry, key), fmt)} |"
                )
        failures = [r for r in self.cells.values() if r.error]
        if failures:
            lines += ["", "## Failed", ""]
            lines += [f"- {r.entry} on {r.scenario}: {r.error}" for r in failures]
        return "\n".join(lines) + "\n"


def _fmt(value: float | None, fmt: str) -> str:
    return "-" if value is None else format(value, fmt)


def build(
    entries: Sequence[str],
    scenarios: Sequence[str],
    results: Sequence[EntryResult],
    dates: tuple[int, int] | None = None,
    map_dates: tuple[str | None, ...] = (),
) -> Leaderboard:
    """Arrange results (any order) into the leaderboard; ``dates``: (reference, flight)
    indices, ``map_dates`` the acquisition date of each index."""
    cells = {(r.entry, r.scenario): r for r in results}
    ref, flight = dates if dates is not None else (None, None)
    return Leaderboard(
        entries=tuple(entries),
        scenarios=tuple(scenarios),
        cells=cells,
        reference_date=ref,
        flight_date=flight,
        map_dates=map_dates,
    )


GAP_FIGURES = (
    "median_m", "p95_m", "recall_5m", "recall_25m", "availability", "fix_rate",
    "longest_without_fix_s",
)  # fmt: skip


def gaps_markdown(boards: Sequence[Leaderboard]) -> str:
    """Leaderboards of one bench flown over several map dates: a summary per date gap (the
    median over scenarios), then each gap's tables."""
    lines = ["# Leaderboard by map date gap", ""]
    lines.append(
        "Map-based methods match the reference map of one date while the camera sees the "
        "flight's date; each column is one gap (the median over scenarios)."
    )
    for key, _path, title, fmt, better in FIGURES:
        if key not in GAP_FIGURES:
            continue
        lines += ["", f"## {title} ({'lower' if better == 'low' else 'higher'} is better)", ""]
        heads = [_gap_head(b) for b in boards]
        lines.append("| method | " + " | ".join(heads) + " |")
        lines.append("|---" * (len(boards) + 1) + "|")
        for entry in boards[0].entries:
            cells = [_fmt(b.summary(entry, key), fmt) for b in boards]
            lines.append(f"| {entry} | " + " | ".join(cells) + " |")
    for board in boards:
        body = board.to_markdown().split("\n")
        lines += ["", f"# {board.gap}", ""]
        lines += [("#" + ln if ln.startswith("## ") else ln) for ln in body[2:]]
    return "\n".join(lines).rstrip("\n") + "\n"


def _gap_head(board: Leaderboard) -> str:
    """A gap's column: ``2009-06-20 -> 2016-04-22`` where the dates are known, else ``0 -> 2``."""
    ends = (board.reference_date, board.flight_date)
    named = [date_name(d, board.map_dates).partition(" (")[2].rstrip(")") for d in ends]
    return " -> ".join(named) if all(named) else " -> ".join(str(d) for d in ends)


def gaps_json(boards: Sequence[Leaderboard]) -> dict[str, Any]:
    """The leaderboards of every gap, in flight-date order."""
    return {"v": 1, "gaps": [b.to_json() for b in boards]}


def scenario_class(scenario: str) -> str:
    """``UC-300`` -> ``urban circle`` (the box plots' groups)."""
    return SCENARIO_CLASSES.get(scenario[:2].upper(), scenario)
