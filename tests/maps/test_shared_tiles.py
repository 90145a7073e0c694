"""Procedural maps sharing their drawn ground through a folder (issue 34): the same pixels as
drawing alone, the squares read back by another map of the same date, not by other dates."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import numpy as np
import pytest

from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.shared_tiles import PREFIX, SharedSurveys, shared_folder
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=10.0)


def test_shared_ground_gives_the_pixels_of_drawing_alone(tmp_path: Path) -> None:
    alone = ProceduralMap("urban", HOME, date=1)
    first = ProceduralMap("urban", HOME, date=1, shared_dir=tmp_path)
    want = alone.read_level(0, 5000, 5000, 300, 200)
    assert np.array_equal(first.read_level(0, 5000, 5000, 300, 200), want)
    saved = sorted(tmp_path.rglob("*.npy"))
    assert saved, "the drawn squares were not saved"
    assert not list(tmp_path.rglob("*.part"))
    assert not list(tmp_path.rglob("*.drawing"))
    # A second map (another process's) reads the squares: spoil one file's pixels to see
    # that they come from the folder, not from drawing again.
    square = np.load(saved[0])
    np.save(saved[0], np.zeros_like(square))
    second = ProceduralMap("urban", HOME, date=1, shared_dir=tmp_path)
    again = second.read_level(0, 5000, 5000, 300, 200)
    assert not np.array_equal(again, want)
    # Another date, and another kind, have folders of their own.
    other = ProceduralMap("urban", HOME, date=2, shared_dir=tmp_path)
    assert np.array_equal(
        other.read_level(0, 5000, 5000, 8, 8),
        ProceduralMap("urban", HOME, date=2).read_level(0, 5000, 5000, 8, 8),
    )
    assert len({p.parent for p in tmp_path.rglob("*.npy")}) == 2


def test_a_folder_that_cannot_be_written_draws_as_usual(tmp_path: Path) -> None:
    blocked = tmp_path / "file"
    blocked.write_text("not a folder")
    shared = ProceduralMap("farmland", HOME, shared_dir=blocked)
    assert np.array_equal(
        shared.read_level(0, 5100, 5100, 64, 64),
        ProceduralMap("farmland", HOME).read_level(0, 5100, 5100, 64, 64),
    )


def test_a_square_another_process_is_drawing_is_waited_for(tmp_path: Path) -> None:
    shared = SharedSurveys(tmp_path, ("urban", 0))
    theirs = np.full((8, 8, 3), 7, dtype=np.uint8)
    shared.folder.mkdir(parents=True)
    claim = shared.folder / "1_2_8_0.6.drawing"
    claim.touch()  # the other process claimed the square and draws it

    def other_process() -> None:
        np.save(shared.folder / "1_2_8_0.6.npy", theirs)
        claim.unlink()

    def draw() -> np.ndarray:
        raise AssertionError("drew a square another process was drawing")

    worker = threading.Timer(0.05, other_process)
    worker.start()
    got = shared.square(1, 2, 8, 0.6, draw)
    worker.join()
    assert np.array_equal(got, theirs)
    # A claim left behind with no square (its drawer could not save it): drawn here.
    (shared.folder / "3_4_8_0.6.drawing").touch()
    (shared.folder / "3_4_8_0.6.drawing").unlink()
    assert np.array_equal(shared.square(3, 4, 8, 0.6, lambda: theirs + 1), theirs + 1)


def test_the_folder_of_a_killed_run_goes_with_the_next_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    gone = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    killed = tmp_path / f"{PREFIX}{gone}-old"
    (killed / "urban-0").mkdir(parents=True)
    running = tmp_path / f"{PREFIX}{os.getppid()}-other"  # a run still going
    running.mkdir()
    with shared_folder() as folder:
        assert folder.parent == tmp_path
        assert folder.is_dir()
        assert not killed.exists()
        assert running.is_dir()
    assert not folder.exists()
