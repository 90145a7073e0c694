"""Flights and maps several test files need, made once per test session for both xdist workers.

Each is built in a folder of the session's base temporary directory that both workers see
(``pytest-N/shared/NAME``, beside the workers' own ``popen-gwK``), under a file lock: the
first worker to ask builds it, the other waits on the lock and then reads it. A build is made
in a temporary folder and renamed to its name only once complete, so a failed or killed
build leaves nothing the next reader would take for finished (that reader builds it again).

What is shared is read-only to the tests: a test that writes into an archive (estimates, a
manifest) works on a copy (:func:`copy_archive`).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest
from filelock import FileLock

from air_sitl.cli import main

REPO = Path(__file__).resolve().parent.parent


def session_folder(config: pytest.Config, factory: pytest.TempPathFactory) -> Path:
    """The folder both xdist workers of this session share (one process's own without xdist)."""
    base = factory.getbasetemp()
    if hasattr(config, "workerinput"):  # an xdist worker: .../pytest-N/popen-gwK
        base = base.parent
    folder = base / "shared"
    folder.mkdir(exist_ok=True)
    return folder


def shared(folder: Path, name: str, build: Callable[[Path], object]) -> Path:
    """``folder/name``, made by ``build(path)`` (which creates ``path``) if no worker has yet."""
    done = folder / name
    with FileLock(str(folder / f"{name}.lock")):
        if done.is_dir():
            return done
        work = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=folder))
        try:
            build(work / name)
            (work / name).rename(done)
        finally:
            shutil.rmtree(work, ignore_errors=True)
    return done


def fly(plan: Path, out: Path, *options: str) -> Path:
    """``air-sitl fly PLAN --out OUT --quiet OPTIONS`` (this checkout's), which must succeed."""
    run = subprocess.run(
        [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(out), "--quiet",
         *options],
        capture_output=True, text=True, timeout=900, check=False, cwd=REPO,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-3000:]
    return out


def fly_uc200_start(out: Path) -> Path:
    """The first 600 frames of UC-200 from the air over the urban map at date 1 (about 10 s of
    CPU): the first 12 s of its circle, banked about 9 degrees; enough for the map-matching
    methods' figures (every frame matched against date 0), a whole circle is not needed.

    The flight stops at 45 s of simulated time, mission unfinished: exit code 1 by design.
    """
    argv = ["fly", str(REPO / "missions" / "UC-200.plan"), "--air-start", "--map-date", "1"]
    assert main([*argv, "--max-sim-time", "45", "--quiet", "--out", str(out)]) == 1
    assert json.loads((out / "manifest.json").read_text())["complete"] is True
    return out


def copy_archive(src: Path, dst: Path, *, images: bool = False) -> Path:
    """A shared archive's files in ``dst`` for a test to write into; its frames hard-linked
    with ``images`` (no bytes copied: nothing rewrites a frame), else left out (scoring and
    eval read rows only)."""
    dst.mkdir(parents=True)
    for path in src.iterdir():
        if path.is_file() and path.suffix != ".jpg":
            shutil.copy2(path, dst / path.name)
        elif path.is_file() and images:
            os.link(path, dst / path.name)
        elif path.is_dir():
            shutil.copytree(path, dst / path.name)
    return dst
