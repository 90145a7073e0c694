"""``air-sitl sweep report DIR``: each metric against each axis, as a table and as plots.

Metrics: errors, recall, availability, the fix rate and the longest time without a map fix
(``-`` for a method without map fixes; per date gap on the ``map-date`` axis), drift. An axis
is an option whose value differs between the runs of ``results.jsonl`` (the SPEC's axes
first, as ``sweep.json`` lists them). ``seed`` is the spread, not an axis, when there is
another one. For each axis value and method: the median over every run with that value (its
seeds and the other axes' values) and the spread as the 25-75 % range. Writes
``DIR/report.md`` and ``DIR/report.png`` (matplotlib, imported only here).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from air_sitl.files import write_bytes_atomic
from air_sitl.localize.mapmatch import reference_date_for
from air_sitl.maps.dates import gap_name
from air_sitl.sweep.errors import SweepError
from air_sitl.sweep.results import RESULTS, latest_rows

REPORT_MD = "report.md"
REPORT_PNG = "report.png"
SPREAD_KEY = "seed"
FLIGHT = "flight"  # the pseudo-method of a sweep without methods: the flight's own figures

Getter = Callable[[dict[str, Any]], Any]


@dataclass(frozen=True, slots=True)
class Metric:
    label: str
    path: tuple[str, ...]
    fmt: str = "{:.2f}"
    fraction: bool = False  # a share from 0 to 1: plotted on that whole scale


EVAL_METRICS = (
    Metric("median horizontal error m", ("horizontal_error_m", "median")),
    Metric("p95 horizontal error m", ("horizontal_error_m", "p95")),
    Metric("recall at 5 m", ("recall", "5m"), "{:.2f}", fraction=True),
    Metric("recall at 25 m", ("recall", "25m"), "{:.2f}", fraction=True),
    Metric("availability", ("availability",), "{:.2f}", fraction=True),
    Metric("fix rate", ("fix_rate",), "{:.2f}", fraction=True),
    Metric("longest without fix s", ("longest_without_fix_s",), "{:.1f}"),
    Metric("final drift % of distance", ("drift_pct",), "{:.1f}"),
)
FLIGHT_METRICS = (
    Metric("max cross-track m", ("max_cross_track_m",)),
    Metric("max altitude error m", ("max_alt_error_m",)),
    Metric("capture frames", ("capture_frames",), "{:.0f}"),
)


@dataclass(frozen=True, slots=True)
class Cell:
    """One (axis value, method, metric): the runs' values summarised."""

    n: int
    median: float | None
    p25: float | None
    p75: float | None


def _dig(obj: Any, path: Sequence[str]) -> float | None:
    for key in path:
        if not isinstance(obj, dict):
            return None
        obj = obj.get(key)
    if isinstance(obj, bool) or not isinstance(obj, int | float) or not math.isfinite(obj):
        return None
    return float(obj)


def _key(value: Any) -> str:
    return json.dumps(value, sort_keys=True)


def _text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def find_axes(rows: Sequence[dict[str, Any]], listed: Sequence[str] = ()) -> list[str]:
    """Options whose value differs between rows (``listed`` first), seed last or out."""
    varying = []
    keys = {k for row in rows for k in (row.get("options") or {})}
    for key in [*listed, *sorted(keys - set(listed))]:
        values = {_key((row.get("options") or {}).get(key)) for row in rows}
        if len(values) > 1 and key not in varying:
            varying.append(key)
    if len(varying) > 1 and SPREAD_KEY in varying:
        varying.remove(SPREAD_KEY)
    return varying


def axis_values(rows: Sequence[dict[str, Any]], axis: str) -> list[Any]:
    """The values an axis takes, numbers in order, anything else in order of appearance."""
    seen: dict[str, Any] = {}
    for row in rows:
        value = (row.get("options") or {}).get(axis)
        seen.setdefault(_key(value), value)
    values = list(seen.values())
    if all(isinstance(v, int | float) and not isinstance(v, bool) for v in values):
        values.sort()
    return values


def summarise(values: Sequence[float]) -> Cell:
    if not values:
        return Cell(0, None, None, None)
    arr = np.asarray(values, dtype=np.float64)
    p25, med, p75 = np.percentile(arr, [25, 50, 75])
    return Cell(len(values), float(med), float(p25), float(p75))


def _entries(rows: Sequence[dict[str, Any]]) -> list[str]:
    names: dict[str, None] = {}
    for row in rows:
        for name in row.get("eval") or {}:
            names.setdefault(name, None)
    return list(names) or [FLIGHT]


def _value_of(row: dict[str, Any], entry: str, metric: Metric) -> float | None:
    if row.get("error"):
        return None
    if entry == FLIGHT:
        return _dig(row.get("summary"), metric.path)
    return _dig((row.get("eval") or {}).get(entry), metric.path)


def table(
    rows: Sequence[dict[str, Any]], axis: str, entries: Sequence[str], metrics: Sequence[Metric]
) -> list[tuple[Any, str, int, int, list[Cell]]]:
    """(axis value, method, runs, failed runs, a Cell per metric) for every value x method."""
    out = []
    for value in axis_values(rows, axis):
        here = [r for r in rows if _key((r.get("options") or {}).get(axis)) == _key(value)]
        failed = sum(1 for r in here if r.get("error"))
        for entry in entries:
            cells = []
            for metric in metrics:
                vals = [v for r in here if (v := _value_of(r, entry, metric)) is not None]
                cells.append(summarise(vals))
            out.append((value, entry, len(here), failed, cells))
    return out


def constant_metrics(
    rows: Sequence[dict[str, Any]], entries: Sequence[str], metrics: Sequence[Metric]
) -> dict[str, str]:
    """The metrics with one value in every run and method (label -> that value, formatted):
    a panel of flat lines says nothing, so the figure names them instead of drawing them."""
    out = {}
    for metric in metrics:
        shown = {
            metric.fmt.format(v)
            for r in rows
            for e in entries
            if (v := _value_of(r, e, metric)) is not None
        }
        if len(shown) == 1 and len(rows) > 1:
            out[metric.label] = shown.pop()
    return out


def _constant_text(constant: dict[str, str]) -> str:
    return "the same in every run: " + ", ".join(f"{k} {v}" for k, v in constant.items())


def _fmt(metric: Metric, cell: Cell, spread: bool) -> str:
    if cell.median is None:
        return "-"
    text = metric.fmt.format(cell.median)
    if spread and cell.n > 1 and cell.p25 is not None and cell.p75 is not None:
        text += f" ({metric.fmt.format(cell.p25)}-{metric.fmt.format(cell.p75)})"
    return text


def date_gaps(rows: Sequence[dict[str, Any]]) -> str:
    """Which map dates the runs compared: map-based methods (``mapmatch``, ``fused``) match a
    reference map of one date while the flight's camera saw another."""
    gaps: dict[tuple[int, int], int] = {}
    named: dict[tuple[int, int], list[str]] = {}  # each world's dates (farmland: its own)
    for row in rows:
        # The date the run flew (summary.json's ``map``), else the option as given
        block = (row.get("summary") or {}).get("map") or {}
        given = str((row.get("options") or {}).get("map-date", 0))
        index = block.get("date_index")
        flight = int(index) if isinstance(index, int) else int(given) if given.isdigit() else 0
        ref = reference_date_for(flight, row.get("reference_date"))
        gaps[(ref, flight)] = gaps.get((ref, flight), 0) + 1
        names = named.setdefault((ref, flight), [])
        if (name := gap_name(ref, flight, block.get("dates") or ())) not in names:
            names.append(name)
    text = ", ".join(
        f"{' / '.join(named[gap])} ({n} run{'' if n == 1 else 's'})"
        for gap, n in sorted(gaps.items())
    )
    return f"Map dates (map-based methods): {text}."


def time_table(rows: Sequence[dict[str, Any]]) -> list[str]:
    """``## Where the time went``: each part of the rows' ``time_s`` summed over the runs, its
    share and its median per run (a run of dates flown once: its share of the flight in
    ``fly``, its own date in ``render``); none when no row has them."""
    timed = [r for r in rows if isinstance(r.get("time_s"), dict)]
    parts: dict[str, list[float]] = {}
    for row in timed:
        for part, seconds in row["time_s"].items():
            if isinstance(seconds, int | float):
                parts.setdefault(str(part), []).append(float(seconds))
    total = sum(sum(v) for v in parts.values())
    if not parts or total <= 0:
        return []
    lines = [
        "## Where the time went",
        "",
        f"{len(timed)} runs, {total:,.0f} s of run time in all (wall seconds inside the runs; "
        "the runs of one flight over several map dates share its `fly` equally, each its "
        "own `render`).",
        "",
        "| part | s | share | median per run s |",
        "|---|---|---|---|",
    ]
    for part, values in parts.items():
        share = sum(values) / total
        lines.append(
            f"| {part} | {sum(values):,.1f} | {share:.0%} | {float(np.median(values)):.2f} |"
        )
    return [*lines, ""]


def markdown(
    rows: Sequence[dict[str, Any]],
    axes: Sequence[str],
    entries: Sequence[str],
    metrics: Sequence[Metric],
    title: str,
    notes: Sequence[str] = (),
) -> str:
    """The report as markdown: counts (and ``notes``: coverage), one table per axis, the
    failed runs."""
    failed = [r for r in rows if r.get("error")]
    hosts = sorted({str(r.get("host")) for r in rows if r.get("host")})
    lines = [
        f"# Sweep report: {title}",
        "",
        f"{len(rows)} runs, {len(failed)} failed, on {', '.join(hosts) or '-'}; "
        f"methods: {', '.join(entries)}. Each cell: the median over the runs with that value "
        "(seeds and the other axes), and in brackets the 25-75 % range.",
        "",
    ]
    if notes:
        lines += [*(f"- {note}" for note in notes), ""]
    if entries != [FLIGHT]:
        lines += [date_gaps(rows), ""]
    constant = constant_metrics(rows, entries, metrics)
    if constant:
        text = _constant_text(constant)
        lines += [text[0].upper() + text[1:] + " (not drawn in the figure).", ""]
    lines += [
        f"![each metric against each axis]({REPORT_PNG})",
        "",
    ]
    for axis in axes:
        lines += [f"## {axis}", ""]
        header = [axis, "method", "runs", "failed", *(m.label for m in metrics)]
        lines += ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        for value, entry, n, nfail, cells in table(rows, axis, entries, metrics):
            shown = [
                _fmt(m, c, i == 0) for i, (m, c) in enumerate(zip(metrics, cells, strict=True))
            ]
            lines.append(
                f"| {_text(value)} | {entry} | {n} | {nfail} | " + " | ".join(shown) + " |"
            )
        lines.append("")
    lines += time_table(rows)
    if failed:
        lines += ["## Failed runs", ""]
        for row in failed:
            opts = " ".join(f"{k}={_text(v)}" for k, v in (row.get("options") or {}).items())
            lines.append(f"- `{row['id']}` {opts}: {row['error']}")
        lines.append("")
    return "\n".join(lines)


def plot(
    rows: Sequence[dict[str, Any]],
    axes: Sequence[str],
    entries: Sequence[str],
    metrics: Sequence[Metric],
    path: Path,
    title: str,
) -> None:
    """One panel per (metric, axis): the median per value and method, bars over 25-75 %."""
    import matplotlib  # about 0.5 s to import: only when a figure is drawn

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # after the backend is chosen

    constant = constant_metrics(rows, entries, metrics)
    # A metric no run has (the fix rate of methods without map fixes) is an empty panel.
    known = [
        m for m in metrics if any(_value_of(r, e, m) is not None for r in rows for e in entries)
    ]
    drawn = [m for m in known if m.label not in constant] or list(metrics[:1])
    ncols = max(1, len(axes))
    fig, grid = plt.subplots(
        # At least 7 inches: one axis keeps the title and the footer whole.
        len(drawn),
        ncols,
        figsize=(max(7.0, 3.6 * ncols + 0.6), 2.4 * len(drawn) + 1.0),
        squeeze=False,
    )
    colours = plt.get_cmap("tab10")
    for col, axis in enumerate(axes):
        values = axis_values(rows, axis)
        rows_of = table(rows, axis, entries, drawn)
        for r, metric in enumerate(drawn):
            ax = grid[r][col]
            for k, entry in enumerate(entries):
                cells = [c[4][r] for c in rows_of if c[1] == entry]
                x = np.arange(len(values)) + (k - (len(entries) - 1) / 2) * 0.08
                med = np.array([np.nan if c.median is None else c.median for c in cells])
                lo = np.array([np.nan if c.p25 is None else c.p25 for c in cells])
                hi = np.array([np.nan if c.p75 is None else c.p75 for c in cells])
                ax.errorbar(
                    x, med, yerr=[med - lo, hi - med], marker="o", ms=4, capsize=3,
                    color=colours(k % 10), label=entry,
                )  # fmt: skip
            ax.set_xticks(np.arange(len(values)), [_text(v) for v in values], fontsize=8)
            ax.set_xlim(-0.5, len(values) - 0.5)
            ax.tick_params(axis="y", labelsize=8)
            ax.grid(alpha=0.3)
            if metric.fraction:
                ax.set_ylim(-0.02, 1.05)
            else:  # errors, drift and counts start at zero: differences read at their size
                ax.set_ylim(bottom=0.0)
            if r == len(drawn) - 1:
                ax.set_xlabel(axis)
            if col == 0:
                ax.set_ylabel(metric.label, fontsize=8)
    grid[0][0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{title}: median and 25-75 % range over seeds and other axes", fontsize=10)
    if constant:
        fig.text(0.5, 0.005, _constant_text(constant), ha="center", va="bottom", fontsize=8)
    fig.tight_layout(rect=(0.0, 0.02 if constant else 0.0, 1.0, 1.0))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _sweep_info(folder: Path) -> dict[str, Any]:
    """``sweep.json`` (the SPEC's path, axes and planned run ids), {} without one."""
    info_path = folder / "sweep.json"
    if not info_path.is_file():
        return {}
    info = json.loads(info_path.read_text(encoding="utf-8"))
    return info if isinstance(info, dict) else {}


def _rows(folder: Path) -> list[dict[str, Any]]:
    rows = list(latest_rows(folder / RESULTS).values())
    if not rows:
        msg = f"{folder / RESULTS}: no runs to report on (run the sweep first)"
        raise SweepError(msg)
    return rows


def coverage_notes(folder: Path) -> list[str]:
    """What the report covers when it is not the whole SPEC: runs done of those planned (a
    sweep still running or interrupted), and the SPEC's axes left out for having one value
    among those runs."""
    rows = _rows(folder)
    info = _sweep_info(folder)
    notes = []
    planned = {str(i) for i in info.get("runs") or []}
    done = {str(r["id"]) for r in rows} & planned if planned else set()
    if planned and len(done) < len(planned):
        notes.append(
            f"partial sweep: {len(done)} of {len(planned)} planned runs have results "
            f"({len(planned) - len(done)} not run yet)"
        )
    listed = [str(a) for a in info.get("axes") or []]
    axes = find_axes(rows, listed)
    for axis in listed:
        values = axis_values(rows, axis)
        if axis not in axes and len(values) == 1:
            notes.append(f"axis {axis} left out: one value among these runs ({_text(values[0])})")
    return notes


def write_report(folder: Path) -> list[Path]:
    """Write ``report.md`` and ``report.png`` for the sweep in ``folder``; their paths."""
    rows = _rows(folder)
    info = _sweep_info(folder)
    listed = [str(a) for a in info.get("axes") or []]
    title = Path(str(info.get("spec") or folder.name)).name
    axes = find_axes(rows, listed)
    if not axes:
        axes = ["id"] if len(rows) > 1 else []
        for row in rows:
            row.setdefault("options", {})["id"] = row["id"]
    entries = _entries(rows)
    metrics = FLIGHT_METRICS if entries == [FLIGHT] else EVAL_METRICS
    md = folder / REPORT_MD
    png = folder / REPORT_PNG
    notes = coverage_notes(folder)
    write_bytes_atomic(md, markdown(rows, axes, entries, metrics, title, notes).encode("utf-8"))
    plot(rows, axes or ["id"], entries, metrics, png, title)
    return [md, png]
