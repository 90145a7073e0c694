"""Box plots of the per-frame horizontal error: one box per method in each scenario class.

matplotlib (Agg) is imported here only, and this module only when a bench writes its plots.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import numpy.typing as npt
from matplotlib.figure import Figure

from air_sitl.bench.leaderboard import SCENARIO_CLASSES, scenario_class

F64 = npt.NDArray[np.float64]


def error_boxes(
    errors: Mapping[tuple[str, str], F64],
    entries: Sequence[str],
    scenarios: Sequence[str],
    out: Path,
    dates: tuple[int, int] | None = None,
) -> Path:
    """Write ``out`` (PNG): log-scale boxes of horizontal error per method per scenario class.

    ``errors[(entry, scenario)]`` are the per-frame errors of the estimated frames; ``dates``
    (reference, flight): the map-date gap, named in the title.
    """
    fig = draw_error_boxes(errors, entries, scenarios, dates)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def draw_error_boxes(
    errors: Mapping[tuple[str, str], F64],
    entries: Sequence[str],
    scenarios: Sequence[str],
    dates: tuple[int, int] | None = None,
) -> Figure:
    """The figure :func:`error_boxes` writes; a method without any estimate is named in the
    legend as such."""
    # The AIR classes in their usual order, then any other scenario under its own name.
    present = {scenario_class(s) for s in scenarios}
    classes = [c for c in SCENARIO_CLASSES.values() if c in present]
    classes += sorted(present - set(classes))
    fig, ax = plt.subplots(
        figsize=(max(6.0, 1.6 * len(classes) * max(1, len(entries)) ** 0.5), 4.6)
    )
    width = 0.8 / max(1, len(entries))
    colours = plt.get_cmap("tab10")
    for k, entry in enumerate(entries):
        data, positions = [], []
        for c, cls in enumerate(classes):
            parts = [
                errors[(entry, s)]
                for s in scenarios
                if scenario_class(s) == cls and (entry, s) in errors
            ]
            values = np.concatenate(parts) if parts else np.empty(0)
            values = values[np.isfinite(values)]
            if values.size:
                data.append(np.maximum(values, 1e-2))
                positions.append(c + (k - (len(entries) - 1) / 2) * width)
        if not data:  # a method that failed or estimated nothing: named, not drawn
            ax.plot([], [], "s", mfc="none", color=colours(k % 10), label=f"{entry} (no estimates)")
            continue
        box = ax.boxplot(
            data,
            positions=positions,
            widths=width * 0.85,
            patch_artist=True,
            whis=(5, 95),
            showfliers=False,
            manage_ticks=False,
        )
        for patch in box["boxes"]:
            patch.set_facecolor(colours(k % 10))
            patch.set_alpha(0.75)
        for median in box["medians"]:
            median.set_color("black")
        ax.plot([], [], "s", color=colours(k % 10), label=entry)
    ax.set_xticks(range(len(classes)), classes)
    ax.set_xlim(-0.5, len(classes) - 0.5)  # every class's slot, whichever boxes were drawn
    ax.set_yscale("log")
    ax.set_ylabel("horizontal error (m)\nbox 25-75 %, whiskers 5-95 %")
    ax.axhline(25.0, color="grey", lw=0.8, ls="--")
    ax.text(len(classes) - 0.55, 25.0, "25 m", va="bottom", ha="right", color="grey", fontsize=8)
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(loc="upper left", fontsize=8, ncols=min(4, len(entries)))
    gap = "" if dates is None else f"\nmap dates: reference {dates[0]} -> flight {dates[1]}"
    ax.set_title(f"Horizontal error per method and scenario class{gap}", fontsize=11)
    fig.tight_layout()
    return fig
