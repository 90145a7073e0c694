"""README's tour runs as written in a fresh checkout, line by line, in order.

The lines are read from README.md itself (the code block under "## A tour") and run with the
``air-sitl`` of this interpreter in an empty folder holding only the checkout's ``missions/``
and ``examples/``, as in a fresh clone. Two lines are changed, because as written they take
minutes or never end:

- ``sweep examples/air_sweep_small.yaml`` (36 runs, about 12 minutes) runs a SPEC made from that
  file with every axis cut to its first value and 45 simulated seconds (12 s of capture): one run;
- ``serve`` (runs until Ctrl-C) gets ``--max-sim-time 5``, a link on a port the kernel picks
  (``--mavlink udpin:127.0.0.1:0``) instead of sending to QGroundControl's and MAVSDK's ports,
  and ``--no-video`` (its video stream would go to QGroundControl's port 5600).

Every other line runs exactly as README writes it, without a warning of frames showing nodata
or ground off the map.
"""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
LINE_TIMEOUT_S = 900.0  # only a hung command gets there


def tour_lines() -> list[str]:
    """The command lines of README's tour, comments included."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    after = text.split("\n## A tour\n", 1)[1]
    block = after.split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


def air_sitl() -> list[str]:
    """The console script installed beside this interpreter, else ``python -m air_sitl``."""
    script = shutil.which("air-sitl", path=str(Path(sys.executable).parent))
    return [script] if script else [sys.executable, "-m", "air_sitl"]


def one_run_spec(folder: Path) -> Path:
    """examples/air_sweep_small.yaml cut to one run of 45 simulated seconds."""
    spec = yaml.safe_load((REPO / "examples" / "air_sweep_small.yaml").read_text())
    spec["axes"] = {key: values[:1] for key, values in spec["axes"].items()}
    spec["base"]["max-sim-time"] = 45
    path = folder / "tour_sweep.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def as_run(argv: list[str], folder: Path) -> list[str]:
    """The command the test runs for one tour line (see the module's docstring)."""
    if argv[1:3] == ["sweep", "examples/air_sweep_small.yaml"]:
        return [*argv[:2], str(one_run_spec(folder)), *argv[3:]]
    if argv[1] == "serve":
        return [*argv, "--max-sim-time", "5", "--mavlink", "udpin:127.0.0.1:0", "--no-video"]
    return argv


def test_the_tour_has_10_to_15_lines_each_a_command() -> None:
    lines = tour_lines()
    assert 10 <= len(lines) <= 15, lines
    assert all(line.startswith("air-sitl ") for line in lines), lines
    assert all(len(line) < 200 for line in lines)
    assert not any("PLAN" in line for line in lines)  # no placeholder to fill in


def test_every_tour_line_runs_as_written(tmp_path: Path) -> None:
    for name in ("missions", "examples"):
        (tmp_path / name).symlink_to(REPO / name)
    for line in tour_lines():
        argv = shlex.split(line, comments=True)
        cmd = air_sitl() + as_run(argv, tmp_path)[1:]
        run = subprocess.run(
            cmd, cwd=tmp_path, capture_output=True, text=True, timeout=LINE_TIMEOUT_S, check=False
        )
        assert run.returncode == 0, f"{line}\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}"
        # A map that does not cover the flight (black wedges in the frames) fails the tour.
        assert "nodata or ground off the map" not in run.stderr, f"{line}\n{run.stderr[-2000:]}"
    out = tmp_path / "out"
    made = [
        "uc200/manifest.json", "uc200-bag/metadata.yaml", "uc200/estimates/mapmatch.csv",
        "fl200-wind/summary.json", "urban-2009.tif", "urban-2016.tif", "uc200-tif/manifest.json",
        "frame.jpg", "air/UC-200.zip", "air/FC-200.zip", "bench/leaderboard.md",
        "bench/date2/leaderboard.md",
        "sweep/results.jsonl", "sweep/report.md",
    ]  # fmt: skip
    missing = [name for name in made if not (out / name).exists()]
    assert not missing, missing
    assert list((out / "plots").glob("*.png"))
