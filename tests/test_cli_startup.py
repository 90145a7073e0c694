"""A command line that answers at once and says its mistakes in one line (issue 25, part 3).

``--help``, ``--version`` and every ``COMMAND --help`` import none of the heavy libraries (the
modules list of ``python -X importtime``, in a fresh interpreter); argparse's mistakes (missing
argument, invalid choice or value, unknown option) are one line naming the command, the option
and the value, and where its help is, with exit 2. Timing is benchmarks/bench_cli.py's job.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest
from cli_errors import one_line_error

from air_sitl.cli import COMMANDS

REPO = Path(__file__).resolve().parent.parent
HEAVY = {
    "numpy", "cv2", "rasterio", "rosbags", "zenoh", "jsbsim", "pymavlink", "mavsdk",
    "matplotlib", "numba", "evo", "scipy", "yaml", "ray",
}  # fmt: skip


def imported_modules(*args: str) -> set[str]:
    """Top-level packages ``python -m air_sitl ARGS`` imported (from -X importtime)."""
    run = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "air_sitl", *args],
        capture_output=True, text=True, timeout=120, check=False, cwd=REPO,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip()  # the help or the version was printed
    return {
        line.rsplit("|", 1)[-1].strip().split(".")[0]
        for line in run.stderr.splitlines()
        if line.startswith("import time:") and "|" in line
    }


HELPS = [["--help"], ["--version"], *([c, "--help"] for c in COMMANDS)]
HELPS += [["map", "make", "--help"], ["map", "fetch", "--help"]]


@pytest.mark.parametrize("args", HELPS, ids=" ".join)
def test_help_and_version_import_no_heavy_library(args: list[str]) -> None:
    heavy = imported_modules(*args) & HEAVY
    assert not heavy, f"air-sitl {' '.join(args)} imported {sorted(heavy)}"


def test_the_check_sees_a_heavy_import() -> None:
    """The runner above does see numpy when it is imported (the test can fail)."""
    run = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import numpy"],
        capture_output=True, text=True, timeout=120, check=True,
    )  # fmt: skip
    assert "| numpy" in run.stderr


# The least each command accepts (parsing only: nothing runs before the mistake is found).
MINIMAL = {
    "fly": ["fly", "x.plan"],
    "serve": ["serve"],
    "dataset": ["dataset"],
    "check": ["check", "DIR"],
    "export": ["export", "DIR", "--tum", "t.txt"],
    "eval": ["eval", "DIR", "--estimate", "x"],
    "localize": ["localize", "--method", "vo"],
    "bench": ["bench", "--out", "DIR"],
    "sweep": ["sweep", "s.yaml"],
    "render": ["render", "--lat", "1", "--lon", "2", "--out", "o.jpg"],
    "map": ["map", "make", "urban", "--out", "a.tif"],
    "camera-bridge": ["camera-bridge"],
    "router": ["router"],
}


def test_every_command_is_covered() -> None:
    assert set(MINIMAL) == set(COMMANDS)


@pytest.mark.parametrize("command", list(MINIMAL))
def test_an_unknown_option_names_the_command_and_its_help(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [*MINIMAL[command], "--bogus=7"]
    where = "map make" if command == "map" else command
    assert one_line_error(argv, capsys) == (
        f"air-sitl: error: {where}: unrecognized arguments: --bogus=7 "
        f"(see `air-sitl {where} --help`)"
    )


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        ([], "the following arguments are required: COMMAND (see `air-sitl --help`)"),
        (["--bogus"], "air-sitl: error: unrecognized arguments: --bogus (see `air-sitl --help`)"),
        (["--bogus", "fly"], "error: unrecognized arguments: --bogus (see `air-sitl --help`)"),
        (["flyy"], "argument COMMAND: invalid choice: 'flyy' (choose from 'fly', 'serve',"),
        (["fly"], "fly: the following arguments are required: PLAN (see `air-sitl fly --help`)"),
        (["fly", "p.plan", "--map-seed", "x"], "fly: argument --map-seed: invalid int value: 'x'"),
        (["fly", "p.plan", "--nav", "gps"], "fly: argument --nav: invalid choice: 'gps'"),
        (["fly", "p.plan", "--wind"], "fly: argument --wind: expected one argument"),
        (["eval", "DIR"], "eval: the following arguments are required: --estimate"),
        (["eval", "DIR", "--estimate", "e", "--align", "x"], "argument --align: invalid choice"),
        (["localize", "--method", "vo", "--every", "2.5"], "invalid int value: '2.5'"),
        (["map"], "map: the following arguments are required: SUBCOMMAND"),
        (["map", "make", "urbann", "--out", "a.tif"], "map make: argument kind: invalid choice"),
        (["map", "make", "urban"], "map make: the following arguments are required: --out"),
        (["sweep", "s.yaml", "--keep", "most"], "sweep: argument --keep: invalid choice: 'most'"),
        (
            ["export", "DIR"],
            "export: one of the arguments --rosbag2 --rosbag1 --tum --mcap is required",
        ),
        (["serve", "--camera", "far"], "serve: argument --camera: invalid choice: 'far'"),
    ],
)
def test_argparse_mistakes_are_one_line_with_exit_2(
    argv: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    line = one_line_error(argv, capsys)
    assert expected in line
    command = " ".join(a for a in argv[:2] if a in COMMANDS or a in ("make", "fetch"))
    if argv and argv[0] not in COMMANDS:
        command = ""
    assert line.endswith(f"(see `air-sitl{' ' + command if command else ''} --help`)"), line


def test_help_still_prints_in_full_and_exits_0(capsys: pytest.CaptureFixture[str]) -> None:
    from air_sitl.cli import main

    assert main(["fly", "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("usage: air-sitl fly") and "--map-date" in out


def test_the_help_constants_of_bench_are_the_real_ones() -> None:
    """bench's --help shows its defaults without importing the bench (kept equal here)."""
    from air_sitl.bench import config
    from air_sitl.commands import bench
    from air_sitl.eval import ALIGNMENTS
    from air_sitl.localize import METHODS

    assert tuple(METHODS) == bench.METHOD_NAMES
    assert bench.ALIGNMENTS == ALIGNMENTS
    assert (bench.FLIGHT_DATES, bench.REFERENCE_DATE) == (
        config.FLIGHT_DATES,
        config.REFERENCE_DATE,
    )


def _command_parser(command: str) -> argparse.ArgumentParser:
    from air_sitl.cli import _parser_for, build_parser

    return _parser_for(build_parser(command), MINIMAL[command])


CHOICES = [
    (command, action.option_strings[-1], tuple(action.choices))
    for command in MINIMAL
    for action in _command_parser(command)._actions
    if action.choices and action.option_strings
]


@pytest.mark.parametrize(("command", "option", "choices"), CHOICES, ids=str)
def test_every_invalid_choice_is_one_line(
    command: str, option: str, choices: tuple[str, ...], capsys: pytest.CaptureFixture[str]
) -> None:
    where = "map make" if command == "map" else command
    line = one_line_error([*MINIMAL[command], option, "nope"], capsys)
    assert line.startswith(f"air-sitl: error: {where}: argument {option}: invalid choice: 'nope'")
    assert line.endswith(f"(see `air-sitl {where} --help`)")


REQUIRED = [c for c in MINIMAL if len(MINIMAL[c]) > 1]


@pytest.mark.parametrize("command", REQUIRED)
def test_every_missing_argument_is_one_line(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = MINIMAL[command][:3] if command == "map" else [command]
    where = "map make" if command == "map" else command
    line = one_line_error(argv, capsys)
    assert line.startswith(f"air-sitl: error: {where}: ")
    assert "required" in line and line.endswith(f"(see `air-sitl {where} --help`)")


def test_a_flight_without_camera_nor_filter_loads_neither(tmp_path: Path) -> None:
    """``fly --no-camera --nav truth`` starts without the camera's modules and numba (issue 34:
    start-up at most 1 s CPU); the onboard filter loads its kernels, built ahead of time
    (without numba: ``air_sitl.compiled``), or numba where they cannot be built."""
    from air_sitl.compiled import machine_code

    built = machine_code("nav") is not None  # built now if it was not
    plan = str(REPO / "missions" / "FR-300.plan")
    loaded = {}
    for nav in ("truth", "ekf"):
        run = subprocess.run(
            [sys.executable, "-X", "importtime", "-m", "air_sitl", "fly", plan, "--no-camera",
             "--quiet", "--nav", nav, "--max-sim-time", "0.1", "--out", str(tmp_path / nav)],
            capture_output=True, text=True, timeout=300, check=False, cwd=REPO,
        )  # fmt: skip
        assert run.returncode == 1, run.stderr[-2000:]  # not completed: files written, exit 1
        loaded[nav] = {
            line.rsplit("|", 1)[-1].strip()
            for line in run.stderr.splitlines()
            if line.startswith("import time:") and "|" in line
        }
    for nav, modules in loaded.items():
        camera = sorted(m for m in modules if m.startswith("air_sitl.camera.") and "render" in m)
        assert not camera, f"fly --no-camera --nav {nav} imported {camera}"
        assert "tqdm" not in modules  # --quiet: no progress line, no tqdm
    assert "numba" not in loaded["truth"] and "air_sitl.nav.kernels" not in loaded["truth"]
    assert "air_sitl.nav.kernels" in loaded["ekf"]  # the check sees the filter's kernels
    assert ("numba" in loaded["ekf"]) is not built
