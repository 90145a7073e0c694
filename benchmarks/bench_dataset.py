"""Speed of recording archives: one 300 m scenario with camera and dataset writing, and all 12.

Usage: python benchmarks/bench_dataset.py [--scenario UC-300] [--all] [--jobs 2] [--keep DIR]

Part 1 flies SCENARIO from the ground as ``air-sitl fly`` does (camera + dataset writer,
``--speed 0``) and prints simulated seconds per wall second over the capture window (target
>= 10, i.e. 500 frames/s), beside JPEG encoding alone of the same frames measured in the same
run (single thread, and the two-thread floor). Part 2 (``--all``) runs
``air-sitl dataset -j JOBS`` on all 12 scenarios and prints the wall time (target < 5 min).
"""

from __future__ import annotations

import argparse
import itertools
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent


def _jpeg_only(folder: Path, quality: int) -> tuple[float, float, int]:
    """Seconds per frame to JPEG-encode the archive's frames: one thread, and two threads."""
    import cv2

    images = [cv2.imread(str(p)) for p in sorted(folder.glob("frame_*.jpg"))]
    params = [cv2.IMWRITE_JPEG_QUALITY, quality]
    t0 = time.perf_counter()
    for img in images:
        cv2.imencode(".jpg", img, params)
    one = (time.perf_counter() - t0) / len(images)
    with ThreadPoolExecutor(2) as pool:
        t0 = time.perf_counter()
        list(pool.map(lambda im: cv2.imencode(".jpg", im, params), images))
        two = (time.perf_counter() - t0) / len(images)
    return one, two, len(images)


def bench_scenario(scenario: str, out: Path) -> None:
    """Part 1: one scenario, capture-window throughput beside JPEG-only encoding."""
    from air_sitl.builder import load_setup
    from air_sitl.camera.model import CameraModel
    from air_sitl.options import FlightOptions
    from air_sitl.recording import RecordingRequest, record_flight

    # (wall, capture frames, sim s, process CPU s), every simulated second
    marks: list[tuple[float, int, float, float]] = []

    def progress(sample: object, flight: object) -> None:
        usage = resource.getrusage(resource.RUSAGE_SELF)
        marks.append(
            (
                time.perf_counter(),
                flight.stats.capture_frames,  # type: ignore[attr-defined]
                sample.state.sim_time_ns / 1e9,  # type: ignore[attr-defined]
                usage.ru_utime + usage.ru_stime,
            )
        )

    camera = CameraModel()
    setup = load_setup(
        REPO / "missions" / f"{scenario}.plan",
        FlightOptions(speed=0.0),
        camera=camera,
        render_workers=2,
    )
    request = RecordingRequest(setup=setup, out=out)
    t0 = time.perf_counter()
    result = record_flight(request, progress=progress)
    total = time.perf_counter() - t0
    capturing = [m for a, m in itertools.pairwise(marks) if m[1] > a[1]]
    first = next(a for a, m in itertools.pairwise(marks) if m[1] > a[1])
    last = capturing[-1]
    frames = last[1] - first[1]
    wall = last[0] - first[0]
    sim = last[2] - first[2]
    per_frame = wall / frames
    cpu_per_frame = (last[3] - first[3]) / frames
    one, two, n = _jpeg_only(out, camera.jpeg_quality)
    sim_total = float(result.summary["sim_time_s"])
    print(f"scenario {scenario}: {result.manifest['frame_count'] if result.manifest else 0} frames")
    print(
        f"  whole flight      {sim_total:7.0f} s simulated in {total:6.1f} s wall "
        f"({sim_total / total:5.1f} x real time, take-off and return included)"
    )
    print(
        f"  capture window    {sim:7.0f} s simulated in {wall:6.1f} s wall "
        f"({sim / wall:5.1f} x real time, {frames / wall:5.0f} frames/s, "
        f"{per_frame * 1e3:5.2f} ms/frame)   target >= 10 x, 500 frames/s: "
        f"{'met' if sim / wall >= 10 else 'NOT met'}"
    )
    print(
        f"  JPEG encode only  {one * 1e3:5.2f} ms/frame on 1 thread ({1 / one:5.0f} frames/s), "
        f"{two * 1e3:5.2f} ms/frame on 2 threads ({1 / two:5.0f} frames/s), {n} frames"
    )
    print(f"  ratio pipeline / JPEG-only (2 threads): {per_frame / two:4.2f}")
    cores = os.cpu_count() or 1
    print(
        f"  CPU per frame     {cpu_per_frame * 1e3:5.2f} ms (all threads: physics, render, "
        f"JPEG, dataset writing) -> on {cores} idle cores at most "
        f"{cores / cpu_per_frame:5.0f} frames/s ({cores / cpu_per_frame / 50:4.1f} x real time)"
    )


def bench_all(jobs: int, out: Path) -> None:
    """Part 2: all 12 scenarios with ``air-sitl dataset -j JOBS``."""
    cmd = [sys.executable, "-m", "air_sitl", "dataset", "--scenarios", "air", "-j", str(jobs)]
    cmd += ["--out", str(out)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    print(proc.stdout.rstrip())
    cores = os.cpu_count() or 1
    print(
        f"CPU used: {cpu:.0f} s -> on {cores} idle cores at best {cpu / cores:.0f} s wall "
        f"({cpu / wall:.2f} cores used in this run)"
    )
    if proc.returncode != 0:
        print(proc.stderr.rstrip()[-2000:])
    print(
        f"all scenarios, -j {jobs}: {wall:.0f} s wall ({wall / 60:.1f} min); target < 5 min: "
        f"{'met' if wall < 300 and proc.returncode == 0 else 'NOT met'} (exit {proc.returncode})"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--scenario", default="UC-300")
    parser.add_argument("--all", action="store_true", help="also fly all 12 with dataset -j")
    parser.add_argument("--only-all", action="store_true", help="skip part 1")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--keep", default=None, help="keep the archives in this folder")
    args = parser.parse_args()
    print(f"cores: {os.cpu_count()}, load average: {os.getloadavg()[0]:.1f}")
    base = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="bench_dataset_"))
    try:
        if not args.only_all:
            bench_scenario(args.scenario, base / args.scenario)
        if args.all or args.only_all:
            bench_all(args.jobs, base / "all")
    finally:
        if not args.keep:
            shutil.rmtree(base, ignore_errors=True)


if __name__ == "__main__":
    main()
