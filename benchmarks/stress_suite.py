"""Run the test suite with busy loops beside it: a test that waits on wall-clock time fails here.

    python benchmarks/stress_suite.py --busy 4 --runs 3 [-- PYTEST ARGS]

Starts ``--busy`` processes that spin on the CPU (this VM has 2 cores, so 4 loops leave the
suite a fraction of a core), runs ``python -m pytest -q`` (with pyproject's addopts: two
xdist workers; ``-- -n 0`` for one process) ``--runs`` times in a row and prints
each run's outcome, wall time and failed tests (the whole output of each run is kept under
``--logs``) beside the same suite's time with no load when ``--baseline`` is given. Exit 0 only
when every loaded run passed.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _spin() -> None:
    x = 0
    while True:
        x = (x * 1103515245 + 12345) & 0x7FFFFFFF


def _run_suite(args: list[str], log: Path) -> tuple[int, float, str, list[str]]:
    """One suite run, its whole output kept in ``log``; (exit, wall s, last line, failures)."""
    t0 = time.monotonic()
    with log.open("w") as out:
        proc = subprocess.run(
            [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", *args],
            cwd=ROOT,
            stdout=out,
            stderr=subprocess.STDOUT,
            text=True,
            check=False,
        )
    lines = log.read_text(errors="replace").strip().splitlines() or [""]
    failures = [line for line in lines if line.startswith(("FAILED ", "ERROR "))]
    return proc.returncode, time.monotonic() - t0, lines[-1], failures


def main(busy: int, runs: int, baseline: bool, logs: Path, pytest_args: list[str]) -> int:
    logs.mkdir(parents=True, exist_ok=True)
    if baseline:
        rc, wall, tail, failures = _run_suite(pytest_args, logs / "no-load.log")
        print(f"no load      : exit {rc}, {wall:7.1f} s  {tail}", flush=True)
        for line in failures:
            print(f"    {line}", flush=True)
    loops = [mp.Process(target=_spin, daemon=True) for _ in range(busy)]
    for p in loops:
        p.start()
    failed = 0
    try:
        for k in range(runs):
            rc, wall, tail, failures = _run_suite(pytest_args, logs / f"busy{busy}-run{k + 1}.log")
            failed += rc != 0
            print(f"{busy} busy, run {k + 1}: exit {rc}, {wall:7.1f} s  {tail}", flush=True)
            for line in failures:
                print(f"    {line}", flush=True)
    finally:
        for p in loops:
            p.terminate()
    print(f"{runs - failed} of {runs} loaded runs passed")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--busy", type=int, default=4, help="busy-loop processes (default 4)")
    parser.add_argument("--runs", type=int, default=3, help="suite runs in a row (default 3)")
    parser.add_argument("--baseline", action="store_true", help="first run once without load")
    parser.add_argument(
        "--logs",
        type=Path,
        default=Path("stress-logs"),
        help="folder for each run's whole pytest output (default ./stress-logs)",
    )
    parser.add_argument("pytest_args", nargs="*", help="passed to pytest (after --)")
    ns = parser.parse_args()
    sys.exit(main(ns.busy, ns.runs, ns.baseline, ns.logs, ns.pytest_args))
