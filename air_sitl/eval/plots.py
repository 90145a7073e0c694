"""Figures of ``air-sitl eval --plots DIR`` (matplotlib's Agg canvas, no pyplot and no global
backend; imported only when figures are asked for).

- ``track_<estimate>.png``: top-down truth and estimate, the estimate coloured by its
  horizontal error, turns marked on the truth;
- ``error_distance.png``: horizontal error against the distance flown, turns shaded;
- ``error_cdf.png``: cumulative distribution of the horizontal error over all capture frames
  (frames without estimate never count as found), with the recall thresholds.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from air_sitl.errors import OptionError
from air_sitl.eval.metrics import RECALL_THRESHOLDS_M
from air_sitl.eval.report import Scored
from air_sitl.eval.trajectory import F64, Bools

TURN_COLOUR = "#f28e2b"
TRUTH_COLOUR = "0.35"
DPI = 110
SMOOTH_FRAMES = 51  # 1 s at 50 Hz
CDF_MAX_M = 250.0
LOG_SPREAD = 20.0
STRETCH_ASPECT = 6.0  # a track longer than this times its width is drawn not to scale


def _slug(name: str) -> str:
    stem = Path(name).name if ("/" in name or "\\" in name) else name
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("_.") or "estimate"


def _runs(mask: Bools) -> list[tuple[int, int]]:
    """(start, end) index pairs, end exclusive, of the runs of True in ``mask``."""
    padded = np.concatenate(([False], mask, [False])).astype(np.int8)
    edges = np.diff(padded)
    return list(
        zip(
            np.flatnonzero(edges == 1).tolist(),
            np.flatnonzero(edges == -1).tolist(),
            strict=True,
        )
    )


def _title(s: Scored) -> str:
    r = s.report
    rmse = r["horizontal_error_m"]["rmse"]
    rmse_txt = "-" if rmse is None else f"{rmse:.1f} m"
    return (
        f"{r['estimate']} ({r['alignment']})  |  {Path(str(r['archive'])).name}  |  "
        f"horizontal RMSE {rmse_txt}, availability {r['availability'] * 100:.1f} %"
    )


def _figure(width_in: float, height_in: float) -> tuple[Figure, Axes]:
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots()


def _save(fig: Figure, path: Path) -> Path:
    try:
        fig.savefig(path, dpi=DPI)
    except OSError as err:
        msg = f"{path}: cannot write: {err.strerror}"
        raise OptionError(msg) from None
    return path


def track(s: Scored, path: Path) -> Path:
    """Top-down truth vs estimate, the estimate coloured by horizontal error, turns marked."""
    truth = s.truth.pos_enu_m
    fig, ax = _figure(8.5, 7.5)
    ax.plot(truth[:, 0], truth[:, 1], color="k", lw=0.8, alpha=0.8, label="truth", zorder=4)
    for k, (a, b) in enumerate(_runs(s.turn)):
        seg = truth[a : max(b, a + 1)]
        ax.plot(
            seg[:, 0],
            seg[:, 1],
            color=TURN_COLOUR,
            lw=9,
            alpha=0.5,
            solid_capstyle="butt",
            label="truth in a turn (> 3 deg/s)" if k == 0 else None,
            zorder=1,
        )
    ax.plot(truth[0, 0], truth[0, 1], "o", color="k", ms=7, label="start", zorder=5)
    if s.est_aligned_m is not None and s.h_err_m is not None and s.h_err_m.size:
        est = s.est_aligned_m
        order = np.argsort(s.h_err_m)  # largest errors on top
        vmax = float(np.percentile(s.h_err_m, 99)) or 1.0
        points = ax.scatter(
            est[order, 0],
            est[order, 1],
            c=s.h_err_m[order],
            cmap="viridis",
            vmin=0.0,
            vmax=vmax,
            s=4,
            lw=0,
            label="estimate",
            zorder=3,
            rasterized=True,
        )
        bar = fig.colorbar(points, ax=ax, shrink=0.8, extend="max")
        bar.set_label("horizontal error (m)")
    span = np.ptp(truth[:, :2], axis=0)
    if max(span) > STRETCH_ASPECT * max(min(span), 1.0):
        ax.set_xlabel("east from home (m), not to scale")  # a line: show the cross-track error
        ax.margins(0.15)
    else:
        ax.set_aspect("equal", adjustable="datalim")
    if not ax.get_xlabel():
        ax.set_xlabel("east from home (m)")
    ax.set_ylabel("north from home (m)")
    ax.grid(True, lw=0.4, alpha=0.5)
    if not s.turn.any():
        ax.plot([], [], color=TURN_COLOUR, lw=9, alpha=0.5, label="turn (> 3 deg/s): none")
    ax.legend(loc="best", fontsize=8, markerscale=2)
    ax.set_title(_title(s), fontsize=9)
    return _save(fig, path)


def _shade_turns(ax: Axes, s: Scored) -> None:
    for k, (a, b) in enumerate(_runs(s.turn)):
        lo = float(s.path_m[a])
        hi = float(s.path_m[min(b, s.path_m.shape[0] - 1)])
        ax.axvspan(lo, hi, color=TURN_COLOUR, alpha=0.18, lw=0, label="turn" if k == 0 else None)


def _rolling_median(y: F64, window: int) -> F64:
    """Centred rolling median (NaN where the window holds no value: gaps stay gaps)."""
    n = y.shape[0]
    if n < window or window < 2:
        return y
    half = window // 2
    padded = np.concatenate((np.full(half, np.nan), y, np.full(window - 1 - half, np.nan)))
    windows = np.lib.stride_tricks.sliding_window_view(padded, window)
    out: F64 = np.full(n, np.nan)
    has = ~np.isnan(windows).all(axis=1)
    out[has] = np.nanmedian(windows[has], axis=1)
    out[np.isnan(y)] = np.nan
    return out


def error_distance(scored: Sequence[Scored], path: Path) -> Path:
    """Horizontal error against the distance flown, one line per estimate, turns shaded."""
    fig, ax = _figure(10, 4.8)
    _shade_turns(ax, scored[0])
    for s in scored:
        if s.h_err_m is None or not s.h_err_m.size:
            continue
        # break the line where frames are missing, so an outage shows as a gap
        x = s.matched.path_m.copy()
        y = s.h_err_m.copy()
        gap = np.flatnonzero(np.diff(s.matched.frame) > 1) + 1
        x = np.insert(x, gap, np.nan)
        y = np.insert(y, gap, np.nan)
        r = s.report
        raw = ax.plot(x, y, lw=0.5, alpha=0.35)[0]
        ax.plot(
            x,
            _rolling_median(y, SMOOTH_FRAMES),
            lw=1.6,
            color=raw.get_color(),
            label=f"{r['estimate']} ({r['alignment']}), 1 s median",
        )
    ax.set_xlabel("distance flown (m, horizontal truth path)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_xlim(0.0, float(scored[0].path_m[-1]) or 1.0)
    p95 = [v for v in (s.report["horizontal_error_m"]["p95"] for s in scored) if v]
    if p95 and max(p95) > LOG_SPREAD * max(min(p95), 1e-3):
        # estimates orders of magnitude apart: a log scale keeps each one readable
        ax.set_yscale("log")
        ax.set_ylabel("horizontal error (m, log scale)")
    else:
        ax.set_ylim(bottom=0.0)
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(
        f"{Path(str(scored[0].report['archive'])).name}: error along the flight", fontsize=9
    )
    return _save(fig, path)


def error_cdf(scored: Sequence[Scored], path: Path) -> Path:
    """CDF of the horizontal error over all capture frames, recall thresholds marked.

    The x axis fits the errors: it ends a little after the largest error of the estimates, or
    at twice an estimate's 95th percentile when its tail runs further (at most ``CDF_MAX_M``):
    errors that end at 4 m fill the figure, an estimate far off leaves it to the right (its
    recall stays read in the legend). Thresholds beyond the axis are not drawn.
    """
    fig, ax = _figure(8.5, 5.2)
    x_max = _cdf_axis_end(scored)
    for s in scored:
        n = s.truth.frames
        err: F64 = np.sort(s.h_err_m) if s.h_err_m is not None else np.empty(0)
        y = np.arange(1, err.size + 1) / n
        r = s.report
        recalls = "/".join(
            "-" if r["recall"][f"{d:g}m"] is None else f"{r['recall'][f'{d:g}m']:.2f}"
            for d in RECALL_THRESHOLDS_M
        )
        label = (
            f"{r['estimate']} ({r['alignment']}): recall {recalls}, "
            f"availability {r['availability']:.1%} (dotted)"
        )
        line = ax.step(
            np.concatenate(([0.0], err)),
            np.concatenate(([0.0], y)),
            where="post",
            lw=1.5,
            label=label,
        )[0]
        colour = line.get_color()
        top = err.size / n if n else 0.0
        ax.plot([err[-1] if err.size else 0.0, 1e9], [top, top], ls=":", lw=1.2, color=colour)
        for d in RECALL_THRESHOLDS_M:
            value = r["recall"][f"{d:g}m"]
            if value is not None:
                ax.plot([d], [value], "o", color=colour, ms=5, zorder=5)
    for d in (d for d in RECALL_THRESHOLDS_M if d <= x_max):
        ax.axvline(d, color="0.5", lw=0.8, ls="--", zorder=0)
        ax.annotate(
            f"{d:g} m",
            (d, 1.03),
            xytext=(0, 3),
            textcoords="offset points",
            ha="center",
            va="bottom",
            fontsize=7,
            color="0.3",
            rotation=90,
        )
    ax.set_xlim(0.0, x_max)
    ax.set_ylim(0.0, 1.03)
    ax.set_xlabel("horizontal error (m)")
    ax.set_ylabel("share of all capture frames with error <= x")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.legend(loc="lower right", fontsize=7.5, title="recall at 5/10/25/50 m", title_fontsize=8)
    ax.set_title(f"{Path(str(scored[0].report['archive'])).name}: error CDF", fontsize=9, pad=26)
    return _save(fig, path)


def _cdf_axis_end(scored: Sequence[Scored]) -> float:
    """Where the CDF's x axis ends (see :func:`error_cdf`)."""
    reach = []
    for s in scored:
        if s.h_err_m is None or s.h_err_m.size == 0:
            continue
        largest = float(np.max(s.h_err_m))
        p95 = s.report["horizontal_error_m"]["p95"]
        reach.append(largest if p95 is None else min(largest, 2.0 * p95))
    if not reach:
        return max(RECALL_THRESHOLDS_M) * 1.1  # nothing to show: the thresholds
    return min(max(1.05 * max(reach), 1.0), CDF_MAX_M)


def write_plots(scored: Sequence[Scored], out_dir: Path) -> list[Path]:
    """Every figure into ``out_dir`` (created); returns the paths written."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"{out_dir}: cannot create the plots folder: {err.strerror}"
        raise OptionError(msg) from None
    paths: list[Path] = []
    seen: set[str] = set()
    for s in scored:
        slug = _slug(str(s.report["estimate"]))
        while slug in seen:
            slug += "_"
        seen.add(slug)
        paths.append(track(s, out_dir / f"track_{slug}.png"))
    paths.append(error_distance(scored, out_dir / "error_distance.png"))
    paths.append(error_cdf(scored, out_dir / "error_cdf.png"))
    return paths
