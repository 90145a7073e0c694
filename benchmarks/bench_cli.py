"""Start-up cost of the command line: ``--help``, ``--version`` and every ``COMMAND --help``.

Run: ``python benchmarks/bench_cli.py [--repeat N] [--top K]``. Prints, for each command line,
the CPU time (user + system) of the child process, the best of N runs, measured with
``resource.getrusage(RUSAGE_CHILDREN)`` around each run, beside the floor measured in the same
run (``python -c pass``: the interpreter alone) and the ratio to it; the target is under 0.3 s
of CPU for each (issue 25). Then the K heaviest imports of ``air-sitl fly --help`` and
``air-sitl --version`` by ``python -X importtime`` (cumulative microseconds), which is where to
look when a figure grows: a command module importing at its top what only its run needs.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
TARGET_S = 0.3


def child_cpu_s(cmd: list[str]) -> float:
    """CPU seconds (user + system) of one run of ``cmd``."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True, cwd=REPO)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def best_cpu_s(cmd: list[str], repeat: int) -> float:
    return min(child_cpu_s(cmd) for _ in range(repeat))


def heaviest_imports(args: list[str], top: int) -> list[tuple[int, str]]:
    """(cumulative us, module) of the ``top`` heaviest imports of ``air-sitl ARGS``."""
    run = subprocess.run(
        [sys.executable, "-X", "importtime", "-m", "air_sitl", *args],
        capture_output=True, text=True, check=True, cwd=REPO,
    )  # fmt: skip
    rows = []
    for line in run.stderr.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _self, cumulative, name = (part.strip() for part in line[12:].split("|"))
        rows.append((int(cumulative), name))  # a package's figure includes what it imports
    return sorted(rows, reverse=True)[:top]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="runs of each, best kept")
    parser.add_argument("--top", type=int, default=8, help="heaviest imports listed")
    args = parser.parse_args()
    sys.path.insert(0, str(REPO))
    from air_sitl.cli import COMMANDS

    script = shutil.which("air-sitl", path=str(Path(sys.executable).parent))
    air = [script] if script else [sys.executable, "-m", "air_sitl"]
    lines = [["--help"], ["--version"], *([c, "--help"] for c in COMMANDS)]
    lines.append(["map", "make", "--help"])
    floor = best_cpu_s([sys.executable, "-c", "pass"], args.repeat)
    load = os.getloadavg()
    print(f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}; {' '.join(air)}")
    print(f"{'command line':32} {'CPU s':>7} {'ratio':>6}")
    print(f"{'python -c pass (floor)':32} {floor:7.3f} {1.0:6.1f}")
    worst = 0.0
    for line in lines:
        cpu = best_cpu_s([*air, *line], args.repeat)
        worst = max(worst, cpu)
        flag = "" if cpu < TARGET_S else f"  over {TARGET_S} s"
        print(f"{'air-sitl ' + ' '.join(line):32} {cpu:7.3f} {cpu / floor:6.1f}{flag}")
    print(f"worst {worst:.3f} s CPU ({worst / floor:.1f}x the floor); target < {TARGET_S} s")
    for what in (["fly", "--help"], ["--version"]):
        print(f"\nheaviest imports of air-sitl {' '.join(what)} (cumulative ms, -X importtime):")
        for us, name in heaviest_imports(what, args.top):
            print(f"  {us / 1000:8.1f}  {name}")


if __name__ == "__main__":
    main()
