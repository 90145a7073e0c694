"""The eval report (SPEC section 5): one dict per (archive, estimate), and its terminal table.

:func:`score` does the maths on a :class:`~air_sitl.eval.trajectory.Truth` and an
:class:`~air_sitl.eval.trajectory.Estimate` (no I/O) and keeps the per-frame arrays the plots
need; :attr:`Scored.report` is the JSON-ready dict with the SPEC keys in the SPEC order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from air_sitl.eval import align as alignment
from air_sitl.eval import metrics
from air_sitl.eval.trajectory import F64, Bools, Estimate, Matched, Truth, match
from air_sitl.eval.turns import turn_mask

REPORT_VERSION = 1


@dataclass(frozen=True, slots=True, kw_only=True)
class Scored:
    """One estimate scored against its archive: the report and the arrays behind it."""

    report: dict[str, Any]
    truth: Truth
    matched: Matched
    turn: Bools  # (N,) per capture frame
    path_m: F64  # (N,) truth horizontal path length per capture frame
    est_aligned_m: F64 | None  # (K, 3), None when the alignment was not computable
    h_err_m: F64 | None  # (K,)


def _ratio(num: float | None, den: float | None) -> float | None:
    if num is None or den is None or den == 0.0:
        return None
    return num / den


def score(truth: Truth, est: Estimate, align: str = "none", archive: str = "") -> Scored:
    """Score ``est`` against ``truth`` after the alignment named."""
    m = match(truth, est)
    n = truth.frames
    path = truth.path_m()
    turn = turn_mask(truth.t_ns, truth.yaw_enu_rad)
    fitted = alignment.fit(align, m.est_enu_m, m.truth_enu_m)
    k = int(m.frame.shape[0])
    distance = float(path[-1]) if n else 0.0

    empty = np.empty(0)
    if fitted is not None:
        est_m = fitted.apply(m.est_enu_m)
        h_err = metrics.horizontal_error_m(est_m, m.truth_enu_m)
        e3 = metrics.error_3d_m(est_m, m.truth_enu_m)
    else:
        est_m, h_err, e3 = None, empty, empty
    turn_k = turn[m.frame]

    def rpe(keep: Bools | None) -> dict[str, Any]:
        if est_m is None:
            return metrics.rpe(np.zeros((0, 3)), np.zeros((0, 3)), empty)
        return metrics.rpe(est_m, m.truth_enu_m, m.path_m, keep=keep)

    def part(in_class: Bools, keep_k: Bools) -> dict[str, Any]:
        return {
            "frames": int(np.count_nonzero(in_class)),
            "horizontal_error_m": metrics.stats(h_err[keep_k] if h_err.size else empty),
            "rpe": rpe(keep_k),
        }

    final = float(h_err[-1]) if h_err.size else None
    straight = part(~turn, ~turn_k)
    turning = part(turn, turn_k)
    estimated = np.zeros(n, dtype=bool)
    estimated[m.frame] = True
    first_fix = None if k == 0 else (int(m.t_ns[0]) - int(truth.t_ns[0])) / 1e9
    if m.has_latency and m.answered_latency_ms.size:
        latency: dict[str, float | None] = {
            "median": float(np.median(m.answered_latency_ms)),
            "p95": float(np.percentile(m.answered_latency_ms, 95)),
        }
    else:
        latency = {"median": None, "p95": None}
    fixed = np.zeros(n, dtype=bool)
    if m.fix_frames is not None:
        fixed[m.fix_frames] = True
    report: dict[str, Any] = {
        "v": REPORT_VERSION,
        "archive": archive or truth.where,
        "estimate": est.name,
        "alignment": align,
        "frames": n,
        "estimated_frames": k,
        "availability": k / n if n else None,
        "fix_rate": None if m.fix_frames is None or not n else m.fix_frames.size / n,
        "longest_without_fix_s": None
        if m.fix_frames is None
        else metrics.longest_run(~fixed) * truth.period_s(),
        "distance_m": distance,
        "horizontal_error_m": metrics.stats(h_err),
        "error_3d_m": metrics.stats(e3),
        "recall": metrics.recall(h_err, n)
        if fitted is not None
        else dict.fromkeys(metrics.recall(empty, n), None),
        "final_error_m": final,
        "drift_pct": None if final is None or distance <= 0.0 else final / distance * 100.0,
        "rpe": rpe(None),
        "straight": straight,
        "turn": turning,
        "turn_straight_rpe_ratio": _ratio(
            turning["rpe"]["100m"]["rmse"], straight["rpe"]["100m"]["rmse"]
        ),
        "latency_ms": latency,
        "time_to_first_fix_s": first_fix,
        "longest_outage_s": metrics.longest_run(~estimated) * truth.period_s(),
    }
    return Scored(
        report=report,
        truth=truth,
        matched=m,
        turn=turn,
        path_m=path,
        est_aligned_m=est_m,
        h_err_m=h_err if est_m is not None else None,
    )


# --- terminal ------------------------------------------------------------------------------

_ROWS: tuple[tuple[str, str, str], ...] = (
    # label, dotted path, format
    ("alignment", "alignment", "s"),
    ("frames", "frames", "d"),
    ("estimated frames", "estimated_frames", "d"),
    ("availability", "availability", "pct"),
    ("fix rate (map fixes)", "fix_rate", "pct"),
    ("longest without fix s", "longest_without_fix_s", ".2f"),
    ("distance m", "distance_m", ".1f"),
    ("horizontal error m  mean", "horizontal_error_m.mean", ".2f"),
    ("                    median", "horizontal_error_m.median", ".2f"),
    ("                    rmse", "horizontal_error_m.rmse", ".2f"),
    ("                    p95", "horizontal_error_m.p95", ".2f"),
    ("                    max", "horizontal_error_m.max", ".2f"),
    ("3-D error m         rmse", "error_3d_m.rmse", ".2f"),
    ("                    max", "error_3d_m.max", ".2f"),
    ("recall  <=5 m", "recall.5m", "pct"),
    ("        <=10 m", "recall.10m", "pct"),
    ("        <=25 m", "recall.25m", "pct"),
    ("        <=50 m", "recall.50m", "pct"),
    ("final error m", "final_error_m", ".2f"),
    ("drift % of distance", "drift_pct", ".2f"),
    ("RPE 100 m  mean / rmse", "rpe.100m", "pair"),
    ("RPE 500 m  mean / rmse", "rpe.500m", "pair"),
    ("straight: frames", "straight.frames", "d"),
    ("  h. error rmse m", "straight.horizontal_error_m.rmse", ".2f"),
    ("  RPE 100 m rmse", "straight.rpe.100m.rmse", ".2f"),
    ("turn: frames", "turn.frames", "d"),
    ("  h. error rmse m", "turn.horizontal_error_m.rmse", ".2f"),
    ("  RPE 100 m rmse", "turn.rpe.100m.rmse", ".2f"),
    ("turn/straight RPE ratio", "turn_straight_rpe_ratio", ".2f"),
    ("latency ms  median / p95", "latency_ms", "latency"),
    ("time to first fix s", "time_to_first_fix_s", ".2f"),
    ("longest outage s", "longest_outage_s", ".2f"),
)


def lookup(report: dict[str, Any], path: str) -> Any:
    """The value at a dotted path (KeyError naming the missing part)."""
    value: Any = report
    for part in path.split("."):
        if not isinstance(value, dict) or part not in value:
            raise KeyError(part)
        value = value[part]
    return value


def _fmt(value: Any, how: str) -> str:
    if how == "pair":
        return f"{_fmt(value['mean'], '.2f')} / {_fmt(value['rmse'], '.2f')}"
    if how == "latency":
        return f"{_fmt(value['median'], '.1f')} / {_fmt(value['p95'], '.1f')}"
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "-"
    if how == "pct":
        return f"{value * 100:.1f} %"
    if how == "s":
        return str(value)
    return format(value, how)


def table(reports: Sequence[dict[str, Any]]) -> str:
    """One screen: a row per figure, a column per estimate ('-' for null)."""
    labels = [label for label, _, _ in _ROWS]
    columns = [[str(r["estimate"])] + [_fmt(lookup(r, p), f) for _, p, f in _ROWS] for r in reports]
    width = max(len(x) for x in labels) + 2
    widths = [max(len(x) for x in col) for col in columns]
    lines = [f"{reports[0]['archive'] if reports else ''}"]
    head = " " * width + "  ".join(c[0].rjust(w) for c, w in zip(columns, widths, strict=True))
    lines.append(head.rstrip())
    for row, label in enumerate(labels, start=1):
        cells = "  ".join(c[row].rjust(w) for c, w in zip(columns, widths, strict=True))
        lines.append(label.ljust(width) + cells)
    return "\n".join(lines)
