"""Real archives for the eval tests, flown once per session for both workers (shared_builds).

``circle``: the AIR scenario UC-200 from its first waypoint (about 3400 frames, nearly all in
a turn). ``line``: a short straight capture leg of 400 m east (about 1300 frames). Both with a
small camera: scoring reads the rows, never the pixels, and the camera changes no row (small
noiseless frames cut UC-200's flight from about 10 s of CPU to 3).
Tests copy an archive's CSV and JSON files (not the frames: scoring needs no image) before
adding estimates to it.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from shared_builds import copy_archive, fly, shared
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.cli import main
from air_sitl.state import GeoPoint

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=38.5387, lon_deg=-121.4935, alt_amsl_m=20.0)


def _fly_circle(out: Path) -> None:
    """Until 110 s: the capture window (33-102 s) whole, not the 200 s of the way home after
    it (the same frames.csv). Stopped there, the mission unfinished: exit code 1 by design."""
    argv = ["fly", str(REPO / "missions" / "UC-200.plan"), "--air-start", *SMALL_CAMERA]
    assert main([*argv, "--max-sim-time", "110", "--quiet", "--out", str(out)]) == 1
    assert json.loads((out / "manifest.json").read_text())["complete"] is True


def _fly_line(out: Path) -> None:
    out.mkdir()
    plan = write_short_plan(out / "UL-T.plan", HOME, leg_m=400.0, name="UL-T")
    fly(plan, out / "UL-T", "--air-start", *SMALL_CAMERA)


@pytest.fixture(scope="session")
def line_flown(shared_folder: Path) -> Path:
    return shared(shared_folder, "eval-line", _fly_line) / "UL-T"


@pytest.fixture(scope="session")
def circle_flown(shared_folder: Path) -> Path:
    return shared(shared_folder, "eval-circle", _fly_circle)


@pytest.fixture
def circle(circle_flown: Path, tmp_path: Path) -> Path:
    return copy_archive(circle_flown, tmp_path / "UC-200")


@pytest.fixture
def line(line_flown: Path, tmp_path: Path) -> Path:
    return copy_archive(line_flown, tmp_path / "UL-T")
