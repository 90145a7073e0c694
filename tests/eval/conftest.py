"""Real archives for the eval tests, flown once per session with a (small) camera.

``circle``: the AIR scenario UC-200 from its first waypoint (about 3400 frames, nearly all in
a turn). ``line``: a short straight capture leg of 400 m east (about 1300 frames).
Tests copy an archive's CSV and JSON files (not the frames: scoring needs no image) before
adding estimates to it.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.state import GeoPoint

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=38.5387, lon_deg=-121.4935, alt_amsl_m=20.0)
# Scoring reads the rows, never the pixels: small noiseless frames halve the flights' CPU.


def _fly(plan: Path, out: Path) -> Path:
    run = subprocess.run(
        [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(out), "--air-start",
         "--quiet", *SMALL_CAMERA],
        capture_output=True, text=True, timeout=600, check=False, cwd=REPO,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    return out


@pytest.fixture(scope="session")
def circle_flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _fly(REPO / "missions" / "UC-200.plan", tmp_path_factory.mktemp("circle") / "UC-200")


@pytest.fixture(scope="session")
def line_flown(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("line")
    plan = write_short_plan(folder / "UL-T.plan", HOME, leg_m=400.0, name="UL-T")
    return _fly(plan, folder / "UL-T")


def copy_archive(src: Path, dst: Path) -> Path:
    """The archive's files without its images (what eval reads)."""
    dst.mkdir(parents=True)
    for path in src.iterdir():
        if path.is_file() and path.suffix != ".jpg":
            shutil.copy2(path, dst / path.name)
    return dst


@pytest.fixture
def circle(circle_flown: Path, tmp_path: Path) -> Path:
    return copy_archive(circle_flown, tmp_path / "UC-200")


@pytest.fixture
def line(line_flown: Path, tmp_path: Path) -> Path:
    return copy_archive(line_flown, tmp_path / "UL-T")
