"""A run both test_mapmatch and test_fused score: ``mapmatch`` over the session's shared flight."""

from __future__ import annotations

from pathlib import Path

import pytest

from air_sitl.dataset.reader import open_archive
from air_sitl.localize.archive import context_of, observations, run_method
from air_sitl.localize.base import Estimate
from air_sitl.localize.mapmatch import MapMatchLocalizer


@pytest.fixture(scope="session")
def mapmatch_on_start(uc200_date1_start: Path) -> tuple[MapMatchLocalizer, list[Estimate]]:
    """The default ``mapmatch`` (against date 0) over ``uc200_date1_start`` (tests/conftest),
    in process: the method (its counters) and its estimates. Read only: made once for the
    files of this folder that a worker runs."""
    method = MapMatchLocalizer()
    with open_archive(uc200_date1_start) as arch:
        source = observations(arch, needs_image=method.needs_image)
        estimates = run_method(method, context_of(arch), source, total=len(arch))
    return method, estimates
