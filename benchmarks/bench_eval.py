"""Speed of ``air-sitl eval``: scoring a 12,000-frame archive, against reading its CSVs.

Usage: python benchmarks/bench_eval.py [ARCHIVE] [--frames 12000] [--repeat 3]

Without ARCHIVE, writes a synthetic archive of --frames frames (``metadata.csv`` and
``frames.csv`` as ``fly`` writes them: a 4.5 km rectangle at 15 m/s, four banked turns) to a
temporary folder; with one, copies its CSV/JSON files (never the images). Adds an estimate
(truth + 5 m noise, 5 % of the frames dropped, latencies) as ``estimates/bench.csv`` and as a
TUM file, then prints the best of --repeat runs of each step beside the floor measured in the
same run: the time to just read the CSV files (``csv.reader`` over every row).
Target: a 12,000-frame archive scored in under 3 s.
"""

from __future__ import annotations

import argparse
import csv
import math
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from air_sitl.dataset.air_schema import AIR_HEADER, FRAMES_COLUMNS, FRAMES_HEADER

PERIOD_NS = 20_000_000
HEADER = (
    "sim_time_ns,frame,east_m,north_m,up_m,lat_deg,lon_deg,alt_amsl_m,qw,qx,qy,qz,"
    "latency_wall_ms,latency_frames\n"
)


def rectangle(frames: int) -> tuple[np.ndarray, np.ndarray]:
    """ENU positions and yaw of a rounded rectangle flown at 15 m/s (0.3 m per frame)."""
    s = np.arange(frames) * 0.3
    side, r = (1050.0, 1050.0), 60.0
    perimeter = 2 * sum(side) - 8 * r + 2 * math.pi * r
    pts = []
    for d in np.mod(s, perimeter):
        pts.append(_on_rectangle(d, side, r))
    pos = np.array(pts)
    d = np.gradient(pos, axis=0)
    yaw = np.arctan2(d[:, 1], d[:, 0])
    up = 200.0 + 0.5 * np.sin(s / 50.0)
    return np.column_stack((pos, up)), yaw


def _on_rectangle(d: float, side: tuple[float, float], r: float) -> tuple[float, float]:
    legs = (side[0] - 2 * r, side[1] - 2 * r, side[0] - 2 * r, side[1] - 2 * r)
    x, y, heading = r, 0.0, 0.0
    for leg in legs:
        if d <= leg:
            return x + d * math.cos(heading), y + d * math.sin(heading)
        d -= leg
        x, y = x + leg * math.cos(heading), y + leg * math.sin(heading)
        arc = math.pi / 2 * r
        cx, cy = x - r * math.sin(heading), y + r * math.cos(heading)
        if d <= arc:
            a = heading - math.pi / 2 + d / r
            return cx + r * math.cos(a), cy + r * math.sin(a)
        d -= arc
        heading += math.pi / 2
        x, y = cx + r * math.cos(heading - math.pi / 2), cy + r * math.sin(heading - math.pi / 2)
    return x, y


def write_synthetic(folder: Path, frames: int) -> None:
    pos, yaw = rectangle(frames)
    folder.mkdir(parents=True)
    meta, extra = [AIR_HEADER], [FRAMES_HEADER]
    filler = ",".join("0" for _ in FRAMES_COLUMNS[7:])
    for k in range(frames):
        e, n, u = pos[k]
        half = yaw[k] / 2
        qz, qw = math.sin(half), math.cos(half)
        meta.append(
            f"frame_{k:06d}.jpg,38.5,-121.5,{u:.4f},0,0,{qz:.9f},{qw:.9f},{e:.4f},{n:.4f},"
            f"{u:.4f},0,0,{qz:.9f},{qw:.9f},{k},{k},nan,nan,nan\n"
        )
        extra.append(
            f"{k},{k * PERIOD_NS},frame_{k:06d}.jpg,38.5,-121.5,{u:.4f},{u:.4f},{filler}\n"
        )
    (folder / "metadata.csv").write_text("".join(meta), encoding="ascii")
    (folder / "frames.csv").write_text("".join(extra), encoding="ascii")


def copy_archive(src: Path, dst: Path) -> None:
    dst.mkdir(parents=True)
    for path in src.iterdir():
        if path.is_file() and path.suffix in (".csv", ".json", ".yaml"):
            shutil.copy2(path, dst / path.name)


def write_estimate(archive: Path, tum: Path) -> int:
    from air_sitl.dataset.reader import open_archive

    with open_archive(archive) as opened:
        t_ns = [opened.timestamp_ns(k) for k in range(len(opened))]
        truth = np.array([r.pose_enu_m for r in opened.rows])
    rng = np.random.default_rng(1)
    n = truth.shape[0]
    keep = np.flatnonzero(rng.random(n) >= 0.05)
    est = truth + rng.normal(0.0, 5.0, truth.shape)
    latency = rng.gamma(2.0, 5.0, n)
    rows = [HEADER]
    tum_lines = []
    for k in keep:
        e, nn, u = est[k]
        rows.append(f"{t_ns[k]},{k},{e:.4f},{nn:.4f},{u:.4f},,,,,,,,{latency[k]:.3f},0\n")
        tum_lines.append(f"{t_ns[k] / 1e9:.9f} {e:.4f} {nn:.4f} {u:.4f} 0 0 0 1\n")
    (archive / "estimates").mkdir(exist_ok=True)
    (archive / "estimates" / "bench.csv").write_text("".join(rows), encoding="ascii")
    tum.write_text("".join(tum_lines), encoding="ascii")
    return n


def best(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def read_csvs(archive: Path) -> int:
    rows = 0
    for name in ("metadata.csv", "frames.csv", "estimates/bench.csv"):
        with (archive / name).open(newline="") as f:
            rows += sum(1 for _ in csv.reader(f))
    return rows


def main() -> None:
    from air_sitl.eval import evaluate, evaluate_many, score_sources

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("archive", nargs="?", default=None)
    parser.add_argument("--frames", type=int, default=12_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_eval_") as tmp:
        archive = Path(tmp) / "archive"
        if args.archive is None:
            write_synthetic(archive, args.frames)
            what = f"synthetic {args.frames}-frame archive"
        else:
            copy_archive(Path(args.archive), archive)
            what = str(args.archive)
        tum = Path(tmp) / "bench.txt"
        frames = write_estimate(archive, tum)
        floor = best(lambda: read_csvs(archive), args.repeat)
        steps: list[tuple[str, float]] = [
            ("eval, --align none", best(lambda: evaluate(archive, "bench"), args.repeat)),
            ("eval, --align posyaw", best(lambda: evaluate(archive, "bench", "posyaw"), 3)),
            ("eval, --align se3", best(lambda: evaluate(archive, "bench", "se3"), 3)),
            ("eval, --align sim3", best(lambda: evaluate(archive, "bench", "sim3"), 3)),
            ("eval of the TUM file", best(lambda: evaluate(archive, str(tum)), args.repeat)),
            (
                "eval of 3 estimates at once",
                best(lambda: evaluate_many(archive, ["bench", str(tum), "svo"]), args.repeat),
            ),
        ]
        from air_sitl.eval.plots import write_plots

        scored = score_sources(archive, ["bench"])
        steps.append(("plots (3 PNGs)", best(lambda: write_plots(scored, Path(tmp) / "p"), 1)))
        cli = [sys.executable, "-m", "air_sitl", "eval", str(archive), "--estimate", "bench"]
        steps.append(
            (
                "air-sitl eval (process)",
                best(lambda: subprocess.run(cli, capture_output=True, check=True), args.repeat),
            )
        )
    print(f"{what}: {frames} frames, estimate with {int(frames * 0.95)} rows (5 % dropped)")
    print(f"{'floor: csv.reader over the 3 CSV files':40s} {floor:7.3f} s")
    for label, seconds in steps:
        print(f"{label:40s} {seconds:7.3f} s   {seconds / floor:5.1f} x floor")
    total = steps[0][1]
    print(f"target: {frames} frames scored in < 3 s -> {'met' if total < 3.0 else 'NOT met'}")


if __name__ == "__main__":
    main()
