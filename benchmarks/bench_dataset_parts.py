"""Where a dataset recording's CPU goes, part by part, and what sharing the drawn ground saves.

Usage: python benchmarks/bench_dataset_parts.py [--scenario UC-300] [--pair UC-300,UR-300]

Part 1 records SCENARIO as ``air-sitl dataset --scenarios SCENARIO -j 1`` does, in this
process, with each part's thread CPU time summed around its function (``time.thread_time``):
the flight's steps (physics, autopilot, EKF, sensors, the archive's CSV rows), the drawing of
the procedural map's ground, the rest of the render (warp, colour, noise), JPEG encoding,
the archive's writing thread and the start-up; per part in seconds, in ms per frame and as a
share of the process's CPU. The floor printed beside them is JPEG encoding alone of the same
frames (the one part no change may touch: the archive's bytes stay the same).

Part 2 (``--pair``) runs ``air-sitl dataset --scenarios PAIR -j 2`` twice, the processes
sharing the drawn ground (what ``dataset`` does since issue 34) and drawing it each on its
own (the code before: ``dataset.share_ground`` replaced by the identity), and prints their CPU
and wall time and that the archives' bytes are the same (summary.json's wall time, and the
manifest's hash of it, aside).
"""

from __future__ import annotations

import argparse
import collections
import functools
import hashlib
import os
import resource
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
_CPU: dict[str, float] = collections.defaultdict(float)
_LOCAL = threading.local()


def _timed(owner: Any, name: str, part: str) -> None:
    """Sum the thread CPU time of ``owner.name`` into ``part`` (outermost calls only)."""
    inner: Callable[..., Any] = getattr(owner, name)

    @functools.wraps(inner)
    def timed(*args: Any, **kwargs: Any) -> Any:
        if getattr(_LOCAL, part, False):
            return inner(*args, **kwargs)
        setattr(_LOCAL, part, True)
        start = time.thread_time()
        try:
            return inner(*args, **kwargs)
        finally:
            _CPU[part] += time.thread_time() - start
            setattr(_LOCAL, part, False)

    setattr(owner, name, timed)


def parts(scenario: str, out: Path) -> None:
    """Part 1: one scenario in this process, part by part."""
    t0 = time.perf_counter()
    from air_sitl import runner
    from air_sitl.camera import render
    from air_sitl.cli import main
    from air_sitl.dataset import writer
    from air_sitl.maps import procedural

    _timed(runner.Flight, "step", "flight")
    _timed(procedural.ProceduralMap, "_acquire", "ground")
    _timed(render.Renderer, "render", "render")
    _timed(render.Renderer, "encode", "jpeg")
    _timed(writer.DatasetWriter, "_handle", "writing")
    flight_run = runner.Flight.run
    start_cpu: list[float] = []

    def run(*args: Any, **kwargs: Any) -> Any:
        start_cpu.append(time.process_time())  # set-up done: imports, plan, map, JSBSim
        return flight_run(*args, **kwargs)

    runner.Flight.run = run  # type: ignore[method-assign]
    rc = main(["dataset", "--scenarios", scenario, "--out", str(out), "-j", "1", "--quiet"])
    wall = time.perf_counter() - t0
    usage = resource.getrusage(resource.RUSAGE_SELF)
    cpu = usage.ru_utime + usage.ru_stime
    frames = len(list((out / scenario).glob("frame_*.jpg")))
    jpeg_alone = _jpeg_alone(out / scenario)
    rows = [
        ("the flight's steps (physics, autopilot, EKF, sensors, CSV rows)", _CPU["flight"]),
        ("drawing the procedural ground (tiles)", _CPU["ground"]),
        ("render less the ground: warp, colour, noise", _CPU["render"] - _CPU["ground"]),
        ("JPEG encoding", _CPU["jpeg"]),
        ("archive writing thread (JPEG files, CSVs)", _CPU["writing"]),
        ("set-up before the first step: imports, plan, map, JSBSim", start_cpu[0]),
    ]
    rows.append(("the rest (sinks' frames, threads, GIL)", cpu - sum(v for _, v in rows)))
    print(f"scenario {scenario}: {frames} frames, exit {rc}, {wall:.1f} s wall, {cpu:.1f} s CPU")
    print(f"  {'part':62s} {'CPU s':>7s} {'ms/frame':>9s} {'share':>6s}")
    for label, seconds in rows:
        print(f"  {label:62s} {seconds:7.2f} {seconds / frames * 1e3:9.2f} {seconds / cpu:6.1%}")
    per_frame = cpu / frames
    print(
        f"  CPU per frame {per_frame * 1e3:.2f} ms; floor, JPEG encoding alone of the same "
        f"frames: {jpeg_alone * 1e3:.2f} ms; ratio {per_frame / jpeg_alone:.1f}x"
    )


def _jpeg_alone(folder: Path) -> float:
    """CPU seconds per frame to encode the archive's frames again (one thread)."""
    import cv2

    from air_sitl.camera.model import CameraModel

    params = [cv2.IMWRITE_JPEG_QUALITY, CameraModel().jpeg_quality]
    images = [cv2.imread(str(p)) for p in sorted(folder.glob("frame_*.jpg"))[::10]]
    start = time.thread_time()
    for image in images:
        assert image is not None
        cv2.imencode(".jpg", image, params)
    return (time.thread_time() - start) / len(images)


def pair(names: str, out: Path) -> None:
    """Part 2: two scenarios at once, sharing the drawn ground and not."""
    digests = {}
    for shared in (True, False):
        folder = out / ("shared" if shared else "alone")
        env = dict(os.environ, PYTHONPATH=str(REPO))
        argv = ["dataset", "--scenarios", names, "-j", "2", "--out", str(folder), "--quiet"]
        # The code before: every job without the shared folder (the workers get the jobs).
        unshare = "" if shared else "d.share_ground = lambda jobs, folder: jobs; "
        code = (
            f"import air_sitl.commands.dataset as d; {unshare}"
            f"from air_sitl.cli import main; raise SystemExit(main({argv!r}))"
        )
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=False
        )
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
        digests[shared] = _archive_digest(folder)
        label = "shared ground" if shared else "each its own"
        print(
            f"  {names} -j 2, {label:13s}: {cpu:6.1f} s CPU, {wall:6.1f} s wall "
            f"(exit {proc.returncode}, load {os.getloadavg()[0]:.1f})"
        )
    same = digests[True] == digests[False]
    print(f"  archives' bytes the same (summary.json's wall time aside): {same}")


def _archive_digest(root: Path) -> str:
    h = hashlib.sha256()
    for path in sorted(root.rglob("*")):
        if path.is_file() and path.name not in ("summary.json", "manifest.json", "stats.csv"):
            h.update(path.relative_to(root).as_posix().encode())
            h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--scenario", default="UC-300")
    parser.add_argument("--pair", default=None, help="two scenarios, e.g. UC-300,UR-300")
    parser.add_argument("--only-pair", action="store_true", help="skip part 1")
    args = parser.parse_args()
    print(f"cores: {os.cpu_count()}, load average: {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="bench_dataset_parts_") as tmp:
        if not args.only_pair:
            parts(args.scenario, Path(tmp) / "one")
        if args.pair:
            pair(args.pair, Path(tmp) / "pair")


if __name__ == "__main__":
    main()
