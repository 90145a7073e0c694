"""The bench's error boxes: every scenario class keeps its slot, a failed method is named."""

from __future__ import annotations

import warnings

import matplotlib.pyplot as plt
import numpy as np

from air_sitl.bench.plots import draw_error_boxes


def test_a_method_without_estimates_is_named_and_the_boxes_sit_over_their_class() -> None:
    errors = {("deadreckon", "UT-200"): np.linspace(0.5, 3.0, 200)}
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # e.g. "Tight layout not applied"
        fig = draw_error_boxes(errors, ["deadreckon", "silent"], ["UT-200"], (0, 2))
    try:
        ax = fig.axes[0]
        assert ax.get_title().endswith("map dates: reference 0 -> flight 2")  # which gap
        legend = ax.get_legend()
        assert legend is not None
        assert [t.get_text() for t in legend.get_texts()] == [
            "deadreckon",
            "silent (no estimates)",
        ]
        # The class's tick is in the middle of its slot, its box inside the slot.
        assert ax.get_xlim() == (-0.5, 0.5)
        assert list(ax.get_xticks()) == [0.0]
        left, right = ax.get_xlim()
        for text in ax.texts:  # the "25 m" mark is drawn inside the axes
            assert left <= text.get_position()[0] <= right, text.get_text()
    finally:
        plt.close(fig)
