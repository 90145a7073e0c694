"""The error CDF's x axis fits the errors it shows (issue 25: not 80 m for errors of 4 m)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from air_sitl.eval import score_sources
from air_sitl.eval.plots import CDF_MAX_M, _cdf_axis_end, write_plots

from .helpers import truth_of, write_estimate


def _offset(archive: Path, name: str, radius_m: float, seed: int) -> None:
    """An estimate off the truth by up to ``radius_m`` horizontally, every frame."""
    truth = truth_of(archive)
    rng = np.random.default_rng(seed)
    angle = rng.uniform(0.0, 2 * np.pi, truth.frames)
    r = radius_m * np.sqrt(rng.uniform(0.0, 1.0, truth.frames))
    off = np.stack([r * np.cos(angle), r * np.sin(angle), np.zeros(truth.frames)], axis=1)
    write_estimate(archive, name, truth.pos_enu_m + off)


def test_the_cdf_axis_ends_just_after_small_errors(line: Path, tmp_path: Path) -> None:
    _offset(line, "small", 4.0, seed=1)
    scored = score_sources(line, ["small"])
    largest = float(np.max(scored[0].h_err_m))
    assert 3.5 < largest <= 4.0
    end = _cdf_axis_end(scored)
    assert largest <= end <= 1.1 * largest  # was 80 m: the 50 m threshold times 1.6
    assert "error_cdf.png" in [p.name for p in write_plots(scored, tmp_path)]


def test_a_long_tail_is_cut_at_twice_the_95th_percentile(line: Path) -> None:
    _offset(line, "small", 4.0, seed=1)
    truth = truth_of(line)
    pos = truth.pos_enu_m.copy()
    pos[:10, 0] += 5000.0  # ten frames 5 km off
    write_estimate(line, "tail", pos)
    scored = score_sources(line, ["small", "tail"])
    end = _cdf_axis_end(scored)
    assert 4.0 < end < 20.0
    far = [s for s in scored if s.report["estimate"] == "tail"]
    assert float(np.max(far[0].h_err_m)) > CDF_MAX_M  # off the figure, its recall in the legend
