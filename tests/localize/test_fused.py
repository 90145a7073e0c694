"""``fused``: dead reckoning + gated map fixes, on a real short flight (urban, date 1 vs 0)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from air_sitl.dataset.reader import open_archive
from air_sitl.localize.archive import context_of, observations, run_method
from air_sitl.localize.base import Estimate
from air_sitl.localize.fused import REACQUIRE_FIXES, FusedLocalizer
from air_sitl.localize.mapmatch import MapMatchLocalizer
from air_sitl.localize.mapmatch_filter import PositionFilter, tilt_jacobian

try:  # the shared flight and scoring (module name depends on tests/localize/__init__.py)
    from test_mapmatch import horizontal_errors, shifted_start, truth_rows
except ImportError:  # pragma: no cover
    from localize.test_mapmatch import horizontal_errors, shifted_start, truth_rows

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def flight(uc200_date1_start: Path) -> Path:
    """The session's shared flight (conftest): read only here."""
    return uc200_date1_start


@pytest.fixture(scope="module")
def runs(
    flight: Path, mapmatch_on_start: tuple[MapMatchLocalizer, list[Estimate]]
) -> tuple[FusedLocalizer, np.ndarray, np.ndarray]:
    """``fused`` and ``mapmatch`` (conftest's run) over the flight: the fused method and both
    error series."""
    rows = truth_rows(flight)
    fused = FusedLocalizer()
    with open_archive(flight) as arch:
        context = context_of(arch)
        e_fused = horizontal_errors(
            run_method(fused, context, observations(arch, needs_image=False), total=len(arch)),
            rows,
        )
    e_mm = horizontal_errors(mapmatch_on_start[1], rows)
    return fused, e_fused, e_mm


def test_fused_meets_the_figures(
    flight: Path, runs: tuple[FusedLocalizer, np.ndarray, np.ndarray]
) -> None:
    fused, e_fused, e_mm = runs
    assert np.all(np.isfinite(e_fused))
    assert float(e_fused.max()) <= 15.0
    assert float(np.percentile(e_fused, 95)) <= float(np.percentile(e_mm, 95))
    assert fused.fixes_fused >= 0.9 * len(truth_rows(flight))
    assert fused.restarts == 0


def test_fused_median_is_no_worse_than_mapmatch(
    runs: tuple[FusedLocalizer, np.ndarray, np.ndarray],
) -> None:
    """The AHRS tilt error biases every map fix by about height x tilt; ``fused`` learns it
    in the turn (``mapmatch`` cannot), so its median is at most ``mapmatch``'s."""
    fused, e_fused, e_mm = runs
    assert float(np.median(e_fused)) <= float(np.median(e_mm))
    assert fused.filter.tilt


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

    east, north = fused.expected_fix()
    for k in range(REACQUIRE_FIXES - 1):
        assert not fused.fuse_fix(east + 40.0, north + 0.1 * k, 2.5)
    assert fused.restarts == 0
    assert not fused.fuse_fix(east + 40.0, north, 2.5)  # the last one restarts the filter
    assert fused.restarts == 1
    # Restarted where the last fix puts the aircraft: that fix is now the one expected.
    after = fused.expected_fix()
    assert math.hypot(after[0] - east - 40.0, after[1] - north) < 1e-6


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


def test_filter_learns_the_tilt_in_a_turn() -> None:
    """Synthetic: a 150 m circle at 300 m with a tilt error of (0.005, -0.004) rad biasing
    every fix; the tilt states take it up and the position loses the bias."""
    tilt = np.array([0.005, -0.004])
    height, speed, radius, dt = 300.0, 20.0, 150.0, 1.0 / 30.0
    rng = np.random.default_rng(3)
    f = PositionFilter(tilt=True)
    f.start(radius, 0.0, 3.0)
    errors = []
    for k in range(1, 30 * 60):
        angle = speed * k * dt / radius
        east, north = radius * math.cos(angle), radius * math.sin(angle)
        heading = math.atan2(-math.sin(angle), math.cos(angle))  # anticlockwise: east, north
        f.predict(dt, (speed * math.sin(heading), speed * math.cos(heading)))
        fix = np.array([east, north]) + tilt_jacobian(height, heading) @ tilt
        fix += rng.normal(0.0, 1.0, 2)
        assert f.update(float(fix[0]), float(fix[1]), 2.5, gate_d2=None, height_m=height,
                        heading=heading)  # fmt: skip
        errors.append(math.hypot(f.position[0] - east, f.position[1] - north))
    assert np.allclose(f.x[4:], tilt, atol=0.0015)  # a circle: along-track is the weaker axis
    assert float(np.median(errors[-600:])) < 0.5  # the bias alone is 1.9 m
