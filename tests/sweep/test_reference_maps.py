"""A sweep worker's reference maps (issue 34): kept from run to run, their ground drawn once
for the pool through its shared folder, the pixels of drawing alone; a run's methods in one
pass, each alone when the pass fails; and the row of a run whose worker died."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from air_sitl.errors import DatasetError
from air_sitl.localize.archive import LocalizeRun
from air_sitl.maps import procedural
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.state import GeoPoint
from air_sitl.sweep import run as sweep_run
from air_sitl.sweep.executors import _crashed_row
from air_sitl.sweep.results import ROW_KEYS
from air_sitl.sweep.run import RunTask, reference_map, share_ground_through

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=10.0)
WINDOW = (1, 2500, 2500, 300, 220)  # level 1: what mapmatch reads at 200 m

OTHER_WORKER = """
import sys
from pathlib import Path
from air_sitl.state import GeoPoint
from air_sitl.sweep.run import reference_map, share_ground_through
share_ground_through(Path(sys.argv[1]))
home = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=10.0)
reference_map("urban", home, seed=0, date=0).read_level(1, 2500, 2500, 300, 220)
"""


@pytest.fixture(autouse=True)
def _fresh_worker(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sweep_run, "_MAPS", type(sweep_run._MAPS)())
    monkeypatch.setattr(sweep_run, "_SHARED_GROUND", [None])


def test_a_reference_drawn_by_one_worker_is_read_by_the_other(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    alone = ProceduralMap("urban", HOME, seed=0, date=0).read_level(*WINDOW)
    # Another worker process of the pool draws the window into the shared folder ...
    subprocess.run([sys.executable, "-c", OTHER_WORKER, str(tmp_path)], check=True, timeout=300)
    assert list(tmp_path.rglob("*.npy"))
    # ... and this one reads it without drawing a square: the same pixels.
    share_ground_through(tmp_path)

    def no_drawing(*_: object, **__: object) -> None:
        raise AssertionError("drew a square the other worker had drawn")

    monkeypatch.setattr(procedural, "acquire", no_drawing)
    mine = reference_map("urban", HOME, seed=0, date=0)
    assert np.array_equal(mine.read_level(*WINDOW), alone)
    # Kept for the worker's next run over the same reference; another date is another map.
    assert reference_map("urban", HOME, seed=0, date=0) is mine
    monkeypatch.undo()
    assert reference_map("urban", HOME, seed=0, date=1) is not mine


def _task() -> RunTask:
    return RunTask(
        id="abc",
        options={"scenario": "UC-200"},
        plan_label="UC-200.plan",
        plan_name="UC-200.plan",
        plan_path="/missions/UC-200.plan",
        plan_text=b"",
        argv=(),
        seed=1,
        archive="/out/runs/abc",
        archive_label="runs/abc",
        reference_date=0,
    )


def test_a_crashed_runs_row_has_every_key() -> None:
    task = _task()
    row = _crashed_row(task, "its worker process died (killed or out of memory)")
    assert set(row) == set(ROW_KEYS)
    assert row["reference_date"] == 0 and row["time_s"] is None and row["error"]


def test_a_failing_pass_runs_each_method_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A pass one method fails: each method alone, so the others are measured and the failing
    one's row says its own reason."""
    passes: list[list[str]] = []

    def one_pass(
        out: Path, methods: list[tuple[str, str, dict[str, object]]], **_: object
    ) -> list[LocalizeRun]:
        passes.append([m for m, _, _ in methods])
        if any(m == "broken" for m, _, _ in methods):
            raise DatasetError(f"{out}: broken cannot read this archive")
        return [
            LocalizeRun(
                path=out / f"{n}.csv", method=m, name=n, frames=3, estimated_frames=3, wall_s=0.1
            )
            for m, n, _ in methods
        ]

    monkeypatch.setattr(sweep_run, "run_archive_methods", one_pass)
    task = _task()
    got = sweep_run._run_methods(task, tmp_path, ["vo", "broken", "deadreckon"])
    assert passes == [["vo", "broken", "deadreckon"], ["vo"], ["broken"], ["deadreckon"]]
    assert isinstance(got["vo"], LocalizeRun) and isinstance(got["deadreckon"], LocalizeRun)
    assert got["broken"] == f"localize broken: {tmp_path}: broken cannot read this archive"
