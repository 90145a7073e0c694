"""``air-sitl bench`` with archives reused: wall and CPU time of the methods x scenarios pass.

    python benchmarks/bench_bench.py --archives out/bench/date1/archives [--map-date 1]
        [--methods all] [-j 2]

Links the archives (hard links: the originals stay untouched) into a fresh bench folder, so
every (scenario, method) is measured anew, runs ``air-sitl bench`` on them and prints its wall
time beside a floor measured in the same run: decoding every JPEG of the archives once on one
core (what any image method pays at least). The target of issue 12: all 12 AIR scenarios x 4
methods within 20 minutes of wall time on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np


def link_archives(src: Path, dst: Path) -> list[str]:
    """Hard-link every complete archive of ``src`` into ``dst`` without its estimates (and the
    logs of external localizers)."""
    names = []
    for folder in sorted(p for p in src.iterdir() if (p / "manifest.json").is_file()):
        target = dst / folder.name
        shutil.copytree(
            folder,
            target,
            copy_function=os.link,
            ignore=shutil.ignore_patterns("estimates", "*.log"),
        )
        names.append(folder.name)
    return names


def decode_floor(archives: Path, names: list[str]) -> tuple[float, int]:
    """Seconds to decode every frame once on this core, and the frame count."""
    cv2.setNumThreads(1)
    t0, n = time.process_time(), 0
    for name in names:
        for jpg in sorted((archives / name).glob("frame_*.jpg")):
            cv2.imdecode(np.fromfile(jpg, np.uint8), cv2.IMREAD_GRAYSCALE)
            n += 1
    return time.process_time() - t0, n


def main(archives: Path, methods: str, jobs: int, keep: bool, map_date: int) -> int:
    work = Path(tempfile.mkdtemp(prefix="bench-bench-"))
    names = link_archives(archives, work / "archives")
    if not names:
        sys.exit(f"{archives}: no complete archive")
    floor_s, frames = decode_floor(work / "archives", names)
    cmd = [sys.executable, "-m", "air_sitl", "bench", "--scenarios", ",".join(names),
           "--methods", methods, "--map-date", str(map_date), "--out", str(work), "-j", str(jobs),
           "--quiet"]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    print(proc.stdout.strip())
    if proc.returncode != 0:
        print(proc.stderr.strip()[-2000:])
    print(f"scenarios {len(names)}, frames {frames}, methods {methods}, -j {jobs}")
    print(
        f"bench wall {wall / 60:6.1f} min   CPU {cpu / 60:6.1f} min   load {os.getloadavg()[0]:.1f}"
    )
    print(f"floor: decoding every frame once, one core {floor_s / 60:6.2f} min "
          f"-> bench wall = {wall / floor_s:5.1f}x the floor")  # fmt: skip
    print(f"target: within 20 min wall -> {'met' if wall <= 1200 else 'NOT met'}")
    if not keep:
        shutil.rmtree(work)
    else:
        print(f"kept in {work}")
    return proc.returncode


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--archives", type=Path, required=True, help="folder of complete archives")
    parser.add_argument("--methods", default="all")
    parser.add_argument("-j", "--jobs", type=int, default=2)
    parser.add_argument("--keep", action="store_true", help="keep the bench folder")
    parser.add_argument("--map-date", type=int, default=1, help="the archives' map date")
    ns = parser.parse_args()
    sys.exit(main(ns.archives, ns.methods, ns.jobs, ns.keep, ns.map_date))
