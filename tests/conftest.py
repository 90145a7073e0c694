"""Shared test set-up: this folder is on sys.path, so tests import the helper modules beside it
(``georef_helpers``, ``short_plans``) whether or not their own folder is a package."""

import compileall
import os
from pathlib import Path

import pytest
from hypothesis import settings
from shared_builds import fly_uc200_start, session_folder, shared

from air_sitl.compiled import build_all

REPO = Path(__file__).resolve().parent.parent

# No per-example deadline: Hypothesis times examples by the wall clock, which the other xdist
# worker (or any load) can stretch past its 200 ms default; the properties are what is tested.
settings.register_profile("air-sitl", deadline=None)
settings.load_profile("air-sitl")

# Each call of a built kernel checked against its signature (air_sitl.compiled): an array of
# another type or layout than declared fails here, rather than being read wrongly.
os.environ.setdefault("AIR_SITL_CHECK_KERNELS", "1")


def pytest_configure(config: pytest.Config) -> None:
    """Byte code of the checkout written once, and our own pytest plugin.

    The tests start hundreds of ``air-sitl`` processes; where PYTHONDONTWRITEBYTECODE is set
    (CI's machine sets it), each would compile every module it imports again (about 0.4 s of
    CPU a process). Python reads byte code already written whatever that variable says, so
    the controller (not each xdist worker) writes it before the first test. The same for the
    compiled kernels (``air_sitl.compiled``): built once, before the workers start (the
    groups side by side on the two cores), not in the first tests that need them, where a
    process waiting on another's build could run past its test's timeout.

    The plugin (the ``air_sitl_vehicle`` fixture) as users get it:

    An install of air-sitl registers it through its ``pytest11`` entry point (named
    ``air_sitl``); a checkout on PYTHONPATH without that install registers it here.
    """
    if not hasattr(config, "workerinput"):
        for folder in ("air_sitl", "bridges", "tests"):
            compileall.compile_dir(REPO / folder, quiet=1)
        build_all()
    if not config.pluginmanager.has_plugin("air_sitl"):
        config.pluginmanager.import_plugin("air_sitl.testing.pytest_plugin")


# The longest test file, first: the docs' commands run in order, one after the other (about 200
# s of one worker); started last, the others would wait for it at the end.
LONGEST_FIRST = ("tests/docs/test_doc_blocks.py",)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Files in :data:`LONGEST_FIRST` before the rest (xdist hands out files in this order)."""
    items.sort(key=lambda item: item.nodeid.split("::")[0] not in LONGEST_FIRST)


@pytest.fixture(scope="session")
def shared_folder(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Where the session's shared flights are built, once for both workers (shared_builds)."""
    return session_folder(request.config, tmp_path_factory)


@pytest.fixture(scope="session")
def uc200_date1_start(shared_folder: Path) -> Path:
    """The first 600 frames of UC-200 from the air over the urban map at date 1 (mapmatch's,
    fused's and the offline baselines' flight, shared_builds.fly_uc200_start). Shared,
    read-only: copy it (shared_builds.copy_archive) before writing into it."""
    return shared(shared_folder, "UC-200-date1-45s", fly_uc200_start)
