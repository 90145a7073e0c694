"""Baseline localizers: accuracy and speed on real archives, one core.

Run: ``python benchmarks/bench_localize.py ARCHIVE... [--methods deadreckon,vo] [--seed 0]``
(archive folders recorded by air-sitl, e.g. copies of ``air-sitl dataset`` output: estimates
are written into them). Pinned to one CPU, OpenCV single-threaded. For each archive and method
it prints:

- horizontal error (median, max) and drift (final error / distance flown, %), the turn/straight
  RPE-100 m ratio: from ``air_sitl.eval`` (SPEC section 5);
- the method's rate: frames/s of ``step`` alone, and of the whole offline driver (CSV, JPEG
  reads, observations) beside the floor measured in the same run: decoding the JPEG at half
  resolution in grey, which the vo method does for every frame. Real time is 50 frames/s.

Measured (2 shared cores, load average 8-11; the AIR scenarios of ``air-sitl dataset``, map
date 1, calm air, seed 0): deadreckon 0.01-0.02 ms per frame; vo 3.4-10 ms (100-300 frames/s,
1.3-4.7x the decode floor), every frame localized. Horizontal error median / max, drift:

    scenario  deadreckon              vo                      vo turn/straight RPE100
    UL-200    5.7 / 16.4 m, 0.63 %    5.2 / 16.8 m, 0.60 %    -
    UC-200    3.2 /  4.5 m, 0.13 %    4.5 /  7.6 m, 0.18 %    0.88
    UR-200    5.7 /  9.3 m, 0.18 %   10.2 / 15.9 m, 0.19 %    1.74
    UL-300    5.5 / 15.8 m, 0.63 %    6.7 / 17.9 m, 0.66 %    -
    UR-300    7.8 / 11.0 m, 0.21 %   13.6 / 20.8 m, 0.25 %    1.71
    FL-200    9.3 / 16.1 m, 0.55 %    9.5 / 18.7 m, 0.60 %    -
    FR-200    5.3 / 10.1 m, 0.21 %    9.5 / 14.4 m, 0.25 %    1.79

In calm air dead reckoning is hard to beat: both drift with the AHRS heading error. With
``fly --wind 5@270`` on UL-200 deadreckon drifts 34 % (the unknown wind), vo 0.38 %.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import cv2
import numpy as np

from air_sitl.dataset.reader import open_archive
from air_sitl.localize.archive import context_of, make_method, observations
from air_sitl.localize.base import Estimate, Localizer, LocalizerContext, Observation
from air_sitl.localize.output import write_estimates


class Timed:
    """A method with a stopwatch around ``step``."""

    def __init__(self, inner: Localizer) -> None:
        self.inner = inner
        self.name = inner.name
        self.needs_image = inner.needs_image
        self.step_s = 0.0

    def reset(self, context: LocalizerContext) -> None:
        self.inner.reset(context)

    def step(self, obs: Observation) -> Estimate | None:
        start = time.perf_counter()
        est = self.inner.step(obs)
        self.step_s += time.perf_counter() - start
        return est


def decode_floor_ms(archive: Path, frames: int = 300) -> float:
    """Milliseconds per frame to decode the JPEG at half resolution in grey."""
    with open_archive(archive) as a:
        jpegs = [a.jpeg(k) for k in range(min(frames, len(a)))]
    start = time.perf_counter()
    for j in jpegs:
        cv2.imdecode(np.frombuffer(j, np.uint8), cv2.IMREAD_REDUCED_GRAYSCALE_2)
    return (time.perf_counter() - start) / len(jpegs) * 1e3


def score(archive: Path, name: str) -> str:
    try:
        from air_sitl.eval import evaluate
    except ImportError:
        return "(air_sitl.eval not available)"
    r = evaluate(archive, name)
    h = r["horizontal_error_m"]
    ratio = r["turn_straight_rpe_ratio"]
    return (
        f"horizontal median {h['median']:7.1f} m  max {h['max']:7.1f} m  "
        f"drift {r['drift_pct']:6.2f} %  turn/straight RPE100 "
        + ("n/a" if ratio is None else f"{ratio:4.2f}")
        + f"  ({r['distance_m']:.0f} m)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("archives", nargs="+", type=Path)
    parser.add_argument("--methods", default="deadreckon,vo")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--cpu", type=int, default=None, help="core to pin to (default: any one)")
    args = parser.parse_args()
    cpu = args.cpu if args.cpu is not None else min(os.sched_getaffinity(0))
    os.sched_setaffinity(0, {cpu})
    cv2.setNumThreads(1)
    print(f"one core (cpu {cpu}), OpenCV threads 1; real time = 50 frames/s")
    for archive in args.archives:
        floor = decode_floor_ms(archive)
        print(f"{archive.name}: floor (JPEG half-res grey decode) {floor:.2f} ms/frame")
        for method in args.methods.split(","):
            timed = Timed(make_method(method))
            with open_archive(archive) as a:
                context = context_of(a, seed=args.seed)
                start = time.perf_counter()
                timed.reset(context)
                estimates = []
                for obs in observations(a, needs_image=timed.needs_image, seed=args.seed):
                    est = timed.step(obs) or Estimate(
                        frame=obs.frame, sim_time_ns=obs.sim_time_ns, enu_m=None
                    )
                    estimates.append(est)
                wall = time.perf_counter() - start
            write_estimates(archive, method, estimates, context.home)
            n = len(estimates)
            step_ms = timed.step_s / n * 1e3
            print(
                f"  {method:<10} step {step_ms:6.2f} ms = {1e3 / step_ms:7.0f} frames/s "
                f"({step_ms / floor:4.1f}x floor); driver+method {n / wall:5.0f} frames/s"
            )
            print(f"  {'':<10} {score(archive, method)}")


if __name__ == "__main__":
    main()
