"""Kernels built ahead of time against numba's JIT (``air_sitl.compiled``): start-up, per
step, first compile.

Usage: python benchmarks/bench_kernels.py [--repeat 3] [--seconds 60] [--cold]

Prints, each beside its floor measured in this run and the ratio to it:

- the start-up: CPU of a 2 s ``fly missions/FR-300.plan --no-camera`` with the onboard EKF,
  with ``--nav truth``, and of a 2 s camera flight over relief (``fly missions/UC-200.plan
  --dem builtin``), each with the built kernels and with numba's JIT (``AIR_SITL_JIT=1``, its
  machine code loaded from numba's disk cache: what every process did before); floor
  ``python -c pass``;
- the EKF's cost per 5 ms step fed as a flight feeds it (IMU, GNSS, baro, airspeed, compass,
  recorded from SECONDS of a JSBSim flight of UC-200), built and JIT; floor: the same feeding
  of a filter that does nothing;
- a frame over relief (forest ``--dem builtin`` at 300 m, rolling 20 deg/s), and the same
  frames over urban relief with every camera effect, ms CPU per frame (every render thread),
  built and JIT; floor: the flat frame of the same states (built);
- with ``--cold``: the first compile, as after an install: every group built into an empty
  cache (C runtime included), against numba's JIT compiling the same kernels into an empty
  cache; the CPU of the process and its children.

Children run alternated, ``--repeat`` times, the best kept (the machine is shared: a slow
spell only ever adds time); their byte code and both caches are made first, unmeasured.
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PLANS = REPO / "missions"
JIT = {"AIR_SITL_JIT": "1"}

STARTUPS = {
    "fly FR-300 --no-camera (EKF)": ["FR-300.plan", "--no-camera"],
    "fly FR-300 --no-camera --nav truth": ["FR-300.plan", "--no-camera", "--nav", "truth"],
    "fly UC-200 --dem builtin (camera, relief)": ["UC-200.plan", "--dem", "builtin"],
}

PER_STEP = """
import sys, time
sys.path.insert(0, {repo!r})
from air_sitl.nav import NavFilter
from tests.nav.flights import feed, record

rec = record("UC-200", {seconds})
steps = rec.steps


class NullFilter:
    def predict(self, imu): ...
    def fuse_gnss(self, fix, now_ns=None): ...
    def fuse_baro(self, sample, now_ns=None): ...
    def fuse_airspeed(self, sample, now_ns=None): ...
    def fuse_heading(self, sample, now_ns=None): ...


def best(make):
    out = float("inf")
    for _ in range(5):
        t = time.process_time()
        nav = make()
        for s in steps:
            feed(nav, s)
        out = min(out, time.process_time() - t)
    return out / len(steps) * 1e6


print(best(lambda: NavFilter(rec.home)), best(NullFilter), "numba" in sys.modules)
"""

FRAMES = """
import math, sys, time
from dataclasses import replace
from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.maps.open import open_map, open_surface
from air_sitl.state import GeoPoint

home = GeoPoint(lat_deg=47.0, lon_deg=8.0, alt_amsl_m=400.0)
every = CameraEffects(enabled=("blur", "rolling-shutter", "vignette", "exposure", "haze",
                               "distortion"))
out = []
for kind, camera, relief in (("forest", CameraModel(), False), ("forest", CameraModel(), True),
                             ("urban", CameraModel(effects=every), True)):
    m = open_map(kind, home, seed=1)
    r = Renderer(m, camera, seed=1, surface=open_surface("builtin", m) if relief else None)
    states = [replace(pose_state(home.lat_deg, home.lon_deg + i * 2e-5, home.alt_amsl_m + 300.0,
                                 alt_agl_m=300.0, roll_rad=0.09, pitch_rad=0.02, yaw_rad=0.3),
                      rate_frd_rad_s=(math.radians(20.0), 0.0, 0.0)) for i in range(25)]
    r.render(states[0])
    best = float("inf")
    for _ in range(3):
        t = time.process_time()
        for s in states:
            r.render(s, noise_index=0)
        best = min(best, (time.process_time() - t) / len(states) * 1e3)
    out.append(best)
print(*out)
"""

WARM_ALL = """
import numpy as np
from air_sitl.camera import effects_kernel, effects_pixels_kernel, relief
from air_sitl.nav.ekf import ErrorStateEkf
from air_sitl.nav.params import NavParams

ErrorStateEkf(NavParams(), 9.8)
relief.warm()
pu, g, nodes = np.zeros((6, 6), np.float32), np.zeros((2, 2)), np.arange(2.0)
effects_kernel.row_maps(pu, pu, 1, 1, np.zeros((4, 9)), 0.0, 0.0, 6, 6, 2, 36,
                        np.zeros((4, 4, 2), np.float32), np.zeros((2, 4), np.int64))
h = np.zeros((2, 9))
effects_kernel.homographies_at(np.zeros((3, 9)), 1.0, np.zeros(2), h)
effects_kernel.grid_paths(h, h, h, g, g, nodes, nodes, g.copy(), g.copy(), np.zeros(4))
effects_kernel.grid_keep(np.zeros(9), g, g, 1.0, 1.0, np.zeros((2, 2), np.float32))
img, one = np.zeros((4, 4, 4), np.uint8), np.ones((4, 4), np.float32)
at = np.tile(np.array([0.0, 1.0, 1.0, 0.0], np.float32), (4, 1))  # keep row 0 for each row
none = np.zeros((0, 0, 3), np.uint8)
effects_pixels_kernel.blur(img, 0, g, g, nodes, nodes, one, at, one, np.zeros(3), True, img.copy())
effects_pixels_kernel.light_total(img, one, at, one, np.zeros(3))
effects_pixels_kernel.light(img, one, at, one, np.zeros(3), 1.0, none, none,
                            np.zeros((4, 4, 3), np.uint8))
"""


def child_env(extra: dict[str, str]) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPATH"] = os.pathsep.join([str(REPO), *filter(None, [env.get("PYTHONPATH")])])
    return {**env, **extra}


def child_cpu_s(cmd: list[str], env: dict[str, str]) -> tuple[float, str]:
    """CPU seconds (user + system) of ``cmd`` and its children; its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    run = subprocess.run(
        cmd, capture_output=True, text=True, check=False, cwd=REPO, env=child_env(env)
    )
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if run.returncode not in (0, 1):  # fly: 1 when the plan is not completed in 2 s
        raise SystemExit(f"{' '.join(cmd)}: exit {run.returncode}\n{run.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, run.stdout


def fly(args: list[str], env: dict[str, str], out: Path) -> float:
    cmd = [sys.executable, "-m", "air_sitl", "fly", str(PLANS / args[0]), *args[1:],
           "--quiet", "--max-sim-time", "2", "--overwrite", "--out", str(out)]  # fmt: skip
    return child_cpu_s(cmd, env)[0]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=3, help="runs of each, best kept")
    parser.add_argument("--seconds", type=float, default=60.0, help="flight fed to the EKF")
    parser.add_argument("--cold", action="store_true", help="also the first compile")
    args = parser.parse_args()
    load0 = os.getloadavg()[0]
    modes = {"built": {}, "JIT": JIT}
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        for env in modes.values():  # byte code, builds and numba's cache made, unmeasured
            for flight in STARTUPS.values():
                fly(flight, env, out / "warm")
        floor = min(child_cpu_s([sys.executable, "-c", "pass"], {})[0] for _ in range(3))
        start = {(name, mode): float("inf") for name in STARTUPS for mode in modes}
        for _ in range(args.repeat):
            for name, flight in STARTUPS.items():
                for mode, env in modes.items():
                    start[name, mode] = min(start[name, mode], fly(flight, env, out / "f"))
        step: dict[str, tuple[float, float]] = {}
        script = PER_STEP.format(repo=str(REPO), seconds=args.seconds)
        for _ in range(args.repeat):
            for mode, env in modes.items():
                _cpu, text = child_cpu_s([sys.executable, "-c", script], env)
                ekf_us, null_us, numba = text.split()
                assert (numba == "True") == (mode == "JIT"), (mode, numba)
                best = step.get(mode, (float("inf"), float("inf")))
                step[mode] = (min(best[0], float(ekf_us)), min(best[1], float(null_us)))
        frames: dict[str, list[float]] = {}
        for _ in range(max(1, args.repeat - 1)):
            for mode, env in modes.items():
                got = [
                    float(v) for v in child_cpu_s([sys.executable, "-c", FRAMES], env)[1].split()
                ]
                frames[mode] = [min(a, b) for a, b in zip(frames.get(mode, got), got, strict=True)]
    print(f"load {load0:.1f} -> {os.getloadavg()[0]:.1f}; best of {args.repeat}; CPU s")
    print(f"{'start-up: a 2 s flight':44s} {'built':>7s} {'JIT':>7s} {'floor':>7s} "
          f"{'built/floor':>11s} {'JIT/floor':>9s} {'built/JIT':>9s}")  # fmt: skip
    for name in STARTUPS:
        b, j = start[name, "built"], start[name, "JIT"]
        print(f"{name:44s} {b:7.2f} {j:7.2f} {floor:7.3f} {b / floor:10.1f}x "
              f"{j / floor:8.1f}x {b / j:8.2f}x")  # fmt: skip
    print(f"{'EKF per 5 ms step, us CPU':44s} {'built':>7s} {'JIT':>7s} {'floor':>7s}")
    floor_us = min(step["built"][1], step["JIT"][1])
    b, j = step["built"][0], step["JIT"][0]
    print(f"{'fed IMU, GNSS, baro, airspeed, compass':44s} {b:7.2f} {j:7.2f} {floor_us:7.2f} "
          f"{b / floor_us:10.1f}x {j / floor_us:8.1f}x {b / j:8.2f}x"
          f"  (floor: a filter doing nothing, fed the same)")  # fmt: skip
    flat = frames["built"][0]
    for k, name in ((1, "frame over relief, forest 300 m, ms CPU"),
                    (2, "urban relief, every effect, ms CPU")):  # fmt: skip
        b, j = frames["built"][k], frames["JIT"][k]
        print(f"{name:44s} {b:7.2f} {j:7.2f} {flat:7.2f} {b / flat:10.1f}x {j / flat:8.1f}x "
              f"{b / j:8.2f}x  (floor: the flat frame)")  # fmt: skip
    if args.cold:
        cold()


def cold() -> None:
    """The first compile of every kernel: built into an empty cache, against the JIT."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-c", WARM_ALL]
        built, _ = child_cpu_s(cmd, {"AIR_SITL_CACHE_DIR": str(Path(tmp) / "built")})
        jit, _ = child_cpu_s(cmd, {**JIT, "NUMBA_CACHE_DIR": str(Path(tmp) / "numba")})
        floor, _ = child_cpu_s(cmd, {})  # both kinds cached: loading only
    print(f"first compile of every kernel (nav, relief, effects), CPU s: built {built:.1f} "
          f"(C runtime included), numba's JIT {jit:.1f}, {built / jit:.2f}x; loading the "
          f"builds {floor:.2f}")  # fmt: skip


if __name__ == "__main__":
    main()
