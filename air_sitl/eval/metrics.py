"""Error statistics, recall, relative pose error over distance, outages (SPEC section 5).

Pure functions on arrays; a statistic over nothing is ``None`` (JSON null), never 0.
"""

from __future__ import annotations

import numpy as np

from air_sitl.eval.trajectory import F64, I64, Bools

Stats = dict[str, float | None]

RECALL_THRESHOLDS_M = (5.0, 10.0, 25.0, 50.0)
RPE_DISTANCES_M = (100.0, 500.0)


def stats(values: F64) -> Stats:
    """mean, median, rmse, p95 and max of ``values`` (all None when empty)."""
    if values.size == 0:
        return {"mean": None, "median": None, "rmse": None, "p95": None, "max": None}
    return {
        "mean": float(np.mean(values)),
        "median": float(np.median(values)),
        "rmse": float(np.sqrt(np.mean(values * values))),
        "p95": float(np.percentile(values, 95)),
        "max": float(np.max(values)),
    }


def mean_rmse(values: F64) -> Stats:
    """mean and rmse of ``values`` (None when empty)."""
    if values.size == 0:
        return {"mean": None, "rmse": None}
    return {"mean": float(np.mean(values)), "rmse": float(np.sqrt(np.mean(values * values)))}


def horizontal_error_m(est_m: F64, truth_m: F64) -> F64:
    """Horizontal distance between estimate and truth per row."""
    diff = est_m[:, :2] - truth_m[:, :2]
    out: F64 = np.hypot(diff[:, 0], diff[:, 1])
    return out


def error_3d_m(est_m: F64, truth_m: F64) -> F64:
    """3-D distance between estimate and truth per row."""
    out: F64 = np.linalg.norm(est_m - truth_m, axis=1)
    return out


def recall(
    h_err_m: F64, frames: int, thresholds_m: tuple[float, ...] = RECALL_THRESHOLDS_M
) -> Stats:
    """Share of all ``frames`` whose horizontal error is at most each threshold.

    Frames without an estimate are misses: the denominator is every capture frame.
    """
    return {
        f"{d:g}m": (float(np.count_nonzero(h_err_m <= d)) / frames if frames else None)
        for d in thresholds_m
    }


def rpe_pairs(path_m: F64, distance_m: float) -> tuple[I64, I64]:
    """Pairs (i, j): for each estimated frame i, the first j at least ``distance_m`` later.

    ``path_m`` is the horizontal truth path length at each estimate, non-decreasing.
    """
    j = np.searchsorted(path_m, path_m + distance_m, side="left")
    i = np.flatnonzero(j < path_m.shape[0])
    return i.astype(np.int64), j[i].astype(np.int64)


def rpe_errors(est_m: F64, truth_m: F64, i: I64, j: I64) -> F64:
    """| (p_j - p_i)_estimate - (p_j - p_i)_truth | (3-D, world frame) for each pair."""
    d = (est_m[j] - est_m[i]) - (truth_m[j] - truth_m[i])
    out: F64 = np.linalg.norm(d, axis=1)
    return out


def rpe(
    est_m: F64,
    truth_m: F64,
    path_m: F64,
    distances_m: tuple[float, ...] = RPE_DISTANCES_M,
    keep: Bools | None = None,
) -> dict[str, Stats]:
    """RPE mean and rmse per distance; ``keep`` selects the pairs by their frame i."""
    out: dict[str, Stats] = {}
    for dist in distances_m:
        i, j = rpe_pairs(path_m, dist)
        if keep is not None:
            sel = keep[i]
            i, j = i[sel], j[sel]
        out[f"{dist:g}m"] = mean_rmse(rpe_errors(est_m, truth_m, i, j))
    return out


def longest_run(missing: Bools) -> int:
    """Length of the longest run of True."""
    if not missing.any():
        return 0
    padded = np.concatenate(([False], missing, [False])).astype(np.int8)
    edges = np.diff(padded)
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)
    return int(np.max(ends - starts))
