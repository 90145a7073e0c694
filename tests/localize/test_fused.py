"""``fused``: dead reckoning + gated map fixes, on a real short flight (urban, date 1 vs 0)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from air_sitl.dataset.reader import open_archive
from air_sitl.localize.archive import context_of, observations, run_method
from air_sitl.localize.fused import REACQUIRE_FIXES, FusedLocalizer
from air_sitl.localize.mapmatch import MapMatchLocalizer

try:  # the shared flight and scoring (module name depends on tests/localize/__init__.py)
    from test_mapmatch import fly_uc200, horizontal_errors, shifted_start, truth_rows
except ImportError:  # pragma: no cover
    from localize.test_mapmatch import fly_uc200, horizontal_errors, shifted_start, truth_rows

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fly_uc200(tmp_path_factory.mktemp("fused") / "uc200")


def test_fused_meets_the_figures_and_is_no_worse_than_mapmatch(flight: Path) -> None:
    rows = truth_rows(flight)
    with open_archive(flight) as arch:
        context = context_of(arch)
        fused = FusedLocalizer()
        e_fused = horizontal_errors(
            run_method(fused, context, observations(arch, needs_image=False), total=len(arch)),
            rows,
        )
        e_mm = horizontal_errors(
            run_method(
                MapMatchLocalizer(), context, observations(arch, needs_image=False), total=len(arch)
            ),
            rows,
        )
    assert np.all(np.isfinite(e_fused))
    assert float(e_fused.max()) <= 15.0
    assert float(np.median(e_fused)) <= float(np.median(e_mm))
    assert fused.fixes_fused >= 0.9 * len(rows)
    assert fused.restarts == 0


def test_fused_gates_out_an_injected_outlier_fix(flight: Path) -> None:
    """A wrong fix 60 m off is refused and leaves the state alone; the flight goes on
    unharmed. Agreeing refused fixes (the filter, not the matcher, is wrong) restart it."""
    rows = truth_rows(flight)
    fused = FusedLocalizer()
    estimates = []
    with open_archive(flight) as arch:
        fused.reset(context_of(arch))
        for obs in observations(arch, needs_image=False):
            est = fused.step(obs)
            assert est is not None
            estimates.append(est)
            if obs.frame == 300:
                before = fused.filter.position
                assert not fused.fuse_fix(before[0] + 60.0, before[1] - 10.0, 2.5)
                assert fused.filter.position == before
                assert fused.fixes_gated == 1
    errors = horizontal_errors(estimates, rows)
    assert float(errors.max()) <= 15.0

    east, north = fused.filter.position
    for k in range(REACQUIRE_FIXES - 1):
        assert not fused.fuse_fix(east + 40.0, north + 0.1 * k, 2.5)
    assert fused.restarts == 0
    assert not fused.fuse_fix(east + 40.0, north, 2.5)  # the last one restarts the filter
    assert fused.restarts == 1
    assert (
        math.hypot(fused.filter.position[0] - east - 40.0, fused.filter.position[1] - north) < 1e-6
    )


def test_fused_restarts_after_a_bad_start(flight: Path) -> None:
    """Started 60 m off with a confident filter: the gate refuses the right fixes at first,
    the search widens, and agreeing refused fixes restart the filter on them."""
    fused = FusedLocalizer()
    with open_archive(flight) as arch:
        source = shifted_start(observations(arch, needs_image=False), 60.0)
        estimates = run_method(fused, context_of(arch), source, total=len(arch))
    errors = horizontal_errors(estimates, truth_rows(flight))
    found = int(np.argmax(errors < 5.0))
    assert 0 < found < 200
    assert fused.restarts == 1
    assert float(errors[found:].max()) <= 15.0
