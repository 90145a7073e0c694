"""Truth and estimate trajectories as arrays, and the matching of each estimate to its truth.

No I/O here: :mod:`air_sitl.eval.sources` parses files into these types. Positions are ENU
metres relative to home (AIR's PoseX..PoseZ), times integer nanoseconds of simulation time.
An estimate row is keyed by its capture frame (truth at that frame's exposure) or, without a
frame, by its simulated time (truth interpolated linearly between the two frames around it,
never the nearest sample). A row may also say whether a map fix was accepted at its frame.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from air_sitl.eval.errors import EvalError

F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
Bools = npt.NDArray[np.bool_]

NO_FRAME = -1  # frame of a row keyed by time only
NO_TIME = -1  # sim_time_ns of a row keyed by frame only


@dataclass(frozen=True, slots=True, kw_only=True)
class Truth:
    """Truth of an archive's capture frames, one entry per frame, in frame order."""

    where: str  # names the archive in messages
    t_ns: I64  # (N,) exposure times
    pos_enu_m: F64  # (N, 3)
    yaw_enu_rad: F64  # (N,) heading of the body x axis, counter-clockwise from east

    @property
    def frames(self) -> int:
        """Number of capture frames."""
        return int(self.t_ns.shape[0])

    def path_m(self) -> F64:
        """Horizontal truth path length flown from the first frame to each frame."""
        step = np.hypot(*np.diff(self.pos_enu_m[:, :2], axis=0).T)
        return np.concatenate(([0.0], np.cumsum(step)))

    def period_s(self) -> float:
        """The frame period (median interval; 20 ms for a single frame)."""
        if self.frames < 2:
            return 0.02
        return float(np.median(np.diff(self.t_ns))) / 1e9


@dataclass(frozen=True, slots=True, kw_only=True)
class Estimate:
    """Validated rows of one estimate source, in file order.

    A row whose position is all NaN is "no estimate" for its frame (it still counts as an
    answer); ``line`` keeps each row's line number in its file for messages.
    """

    name: str  # as the user gave it
    where: str  # the file, for messages
    line: I64  # (M,)
    frame: I64  # (M,) NO_FRAME when keyed by time
    t_ns: I64  # (M,) NO_TIME when keyed by frame only
    pos_enu_m: F64  # (M, 3), NaN rows = no estimate
    latency_wall_ms: F64 | None  # (M,) NaN when absent; None when the source has no latency
    fix: F64 | None = None  # (M,) 1 accepted map fix, 0 none, NaN unsaid; None: no column


@dataclass(frozen=True, slots=True, kw_only=True)
class Matched:
    """The estimated frames of one estimate with their truth, sorted by frame."""

    frame: I64  # (K,) capture frame of each estimate
    t_ns: I64  # (K,) the estimate's time (its frame's exposure when keyed by frame)
    est_enu_m: F64  # (K, 3)
    truth_enu_m: F64  # (K, 3) truth at the estimate's exposure time
    path_m: F64  # (K,) horizontal truth path length at that time
    answered_latency_ms: F64  # latencies of every answered row (NaN-free; empty if none)
    has_latency: bool
    fix_frames: I64 | None = None  # capture frames with an accepted map fix; None: not said


def _nearest_frame(t_frames: I64, t: I64) -> I64:
    j = np.clip(np.searchsorted(t_frames, t), 1, max(len(t_frames) - 1, 1))
    before = np.abs(t - t_frames[j - 1]) <= np.abs(t_frames[np.minimum(j, len(t_frames) - 1)] - t)
    return np.where(before, j - 1, j).astype(np.int64)


def _refuse_first(est: Estimate, bad: Bools, what: Callable[[int], str]) -> None:
    """EvalError naming the line of the first row where ``bad`` holds, and ``what(row)``."""
    if bad.any():
        k = int(np.argmax(bad))
        msg = f"{est.where}: line {est.line[k]}: {what(k)}"
        raise EvalError(msg)


def match(truth: Truth, est: Estimate) -> Matched:
    """Each estimate row with the truth at its exposure time (see the module docstring).

    Raises :class:`EvalError` for a frame outside the archive, a time outside the capture
    window, or two rows for one frame.
    """
    n = truth.frames
    by_frame: Bools = np.asarray(est.frame != NO_FRAME)
    bad = by_frame & ((est.frame < 0) | (est.frame >= n))
    _refuse_first(
        est, bad, lambda k: f"frame {est.frame[k]} is outside the archive (frames 0..{n - 1})"
    )
    by_time: Bools = ~by_frame
    t_frames = truth.t_ns
    window = f"{t_frames[0] / 1e9:.3f}..{t_frames[-1] / 1e9:.3f} s"
    outside = by_time & ((est.t_ns < t_frames[0]) | (est.t_ns > t_frames[-1]))
    _refuse_first(
        est,
        outside,
        lambda k: (
            f"time {est.t_ns[k] / 1e9:.9f} s is outside the archive's capture window ({window})"
        ),
    )
    frame = est.frame.copy()
    if by_time.any():
        frame[by_time] = _nearest_frame(t_frames, est.t_ns[by_time])
    order = np.argsort(frame, kind="stable")
    repeat = np.flatnonzero(frame[order][1:] == frame[order][:-1])
    if repeat.size:
        first, second = sorted((int(order[repeat[0]]), int(order[repeat[0] + 1])))
        how = "frame" if by_frame[second] else "time maps to frame"
        msg = (
            f"{est.where}: line {est.line[second]}: {how} {frame[second]} already estimated "
            f"at line {est.line[first]} (one estimate per frame)"
        )
        raise EvalError(msg)

    has_pos: Bools = np.asarray(np.isfinite(est.pos_enu_m).all(axis=1))
    rows = order[has_pos[order]]
    keyed_by_time = by_time[rows]
    t_row = np.where(keyed_by_time, est.t_ns[rows], t_frames[frame[rows]])
    truth_pos = truth.pos_enu_m[frame[rows]].copy()
    path_all = truth.path_m()
    path = path_all[frame[rows]].copy()
    if keyed_by_time.any():
        t = t_row[keyed_by_time].astype(np.float64)
        tf = t_frames.astype(np.float64)
        for axis in range(3):
            truth_pos[keyed_by_time, axis] = np.interp(t, tf, truth.pos_enu_m[:, axis])
        path[keyed_by_time] = np.interp(t, tf, path_all)
    fix_frames = None
    if est.fix is not None and np.isfinite(est.fix).any():
        fix_frames = np.unique(frame[est.fix == 1.0]).astype(np.int64)
    latency = np.empty(0, dtype=np.float64)
    if est.latency_wall_ms is not None:
        latency = est.latency_wall_ms[np.isfinite(est.latency_wall_ms)]
    return Matched(
        frame=frame[rows],
        t_ns=t_row.astype(np.int64),
        est_enu_m=est.pos_enu_m[rows],
        truth_enu_m=truth_pos,
        path_m=path,
        answered_latency_ms=latency,
        has_latency=est.latency_wall_ms is not None,
        fix_frames=fix_frames,
    )
