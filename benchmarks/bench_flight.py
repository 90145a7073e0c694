"""Speed of the flight step: ``fly --no-camera`` per 5 ms step against bare JSBSim, same run.

Usage: python benchmarks/bench_flight.py [SCENARIO] [--repeat 2] [--dem builtin|FILE]
[--paired-seconds 0] [--parts-seconds 0]

Prints three figures, each beside the floor measured in this run and the ratio to it:

- the floor: JSBSim's own ``FGFDMExec.run()`` of the same aircraft in the air (trimmed at the
  plan's air start), CPU per frame, best of 5 blocks before the flights and 5 after;
- ``fly PLAN --no-camera`` (the onboard EKF, the command's default) flown to the end of the
  plan (SCENARIO, default FR-300: about 12 simulated minutes) as a user runs it, CPU per 5 ms
  step with its start-up left out: (CPU of the whole flight - CPU of a 2 s flight) / (steps
  of the whole flight - steps of the 2 s flight);
- the same with ``--nav truth``;
- the start-up: the CPU of that 2 s ``fly --no-camera`` (interpreter, imports, plan, JSBSim
  load and trim, files), against ``python -c pass``.

Whole flights run in child processes (their CPU from ``getrusage``), ``--repeat`` times each,
alternated, the best kept: the machine is shared and a slow spell only ever adds time. The
children run as an installed program does: with its byte code compiled (one unmeasured start
first; ``PYTHONDONTWRITEBYTECODE`` is dropped from their environment, else every start would
compile the sources again) and numba's kernels in their cache.
``--parts-seconds S`` prints where a step's time goes (the profile of issue 34): each part of
``Flight.step`` timed in place over S simulated seconds of cruise, per step, for both navs.
``--dem`` adds a truth flight over that relief, ``--paired-seconds S`` the filter's own cost
from a truth and an EKF flight stepped side by side in alternating chunks for S simulated
seconds (the figure a busy machine moves least).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from air_sitl.builder import FlightSetup, build_flight, load_setup
from air_sitl.clock import NS_PER_S, PHYSICS_STEP_NS
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.options import FlightOptions
from air_sitl.runner import assemble_flight

REPO = Path(__file__).resolve().parent.parent
CHUNK = 500  # physics steps a flight runs before the other takes its turn (--paired-seconds)
FLOOR_STEPS = 20_000


def children_cpu_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def child_env() -> dict[str, str]:
    """The environment of the flights: byte code written and read, as an installed program."""
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    return env


def fly_cpu(plan: Path, *extra: str) -> tuple[float, int]:
    """CPU seconds of one ``fly --no-camera`` process and the physics steps it flew."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        c0 = children_cpu_s()
        run = subprocess.run(
            [sys.executable, "-m", "air_sitl", "fly", str(plan), "--no-camera", "--quiet",
             "--out", str(out), *extra],
            capture_output=True, text=True, check=False, cwd=REPO, env=child_env(),
        )  # fmt: skip
        cpu = children_cpu_s() - c0
        if run.returncode not in (0, 1):
            raise SystemExit(f"fly {plan.name} {' '.join(extra)} failed: {run.stderr.strip()}")
        summary = json.loads((out / "summary.json").read_text())
    steps = round(summary["sim_time_s"] * NS_PER_S / PHYSICS_STEP_NS) + 1
    return cpu, steps


def python_pass_cpu() -> float:
    c0 = children_cpu_s()
    subprocess.run([sys.executable, "-c", "pass"], check=True)
    return children_cpu_s() - c0


def bare_frame_s(setup: FlightSetup) -> float:
    """CPU seconds of one bare ``FGFDMExec.run()`` of the aircraft trimmed at the air start."""
    air = replace(setup, options=replace(setup.options, air_start=True, nav="truth"))
    flight, _, _ = assemble_flight(air.mission, air.options, home=air.home)
    assert isinstance(flight.fdm, JSBSimModel)
    run = flight.fdm._fdm.run  # the floor: JSBSim's own frame, no property reads, no Python state
    best = float("inf")
    for _ in range(5):
        c0 = time.process_time()
        for _ in range(FLOOR_STEPS):
            run()
        best = min(best, time.process_time() - c0)
    return best / FLOOR_STEPS


def step_parts(
    setup: FlightSetup, nav: str, seconds: float
) -> tuple[float, list[tuple[str, float]]]:
    """Where a step's time goes: CPU us per step of the whole step and of each part of
    ``Flight.step`` (timed in place by wrappers on the wall clock, scaled by the step's CPU
    over its wall time: a shared machine's waits spread evenly; indented parts lie inside the
    part above), over ``seconds`` of cruise after 200 s of the flight."""
    from air_sitl.flightlog import NavTrajectoryWriter, TrajectoryWriter

    with tempfile.TemporaryDirectory() as tmp:
        kind = NavTrajectoryWriter if nav == "ekf" else TrajectoryWriter
        writer = kind(Path(tmp) / "trajectory.csv")
        flight = build_flight(
            replace(setup, options=replace(setup.options, nav=nav)), sinks=[writer]
        )
        for _ in range(200 * 200):  # take-off and climb: the cruise is most of a flight
            flight.step()
        spent: dict[str, float] = {}
        clock = time.perf_counter

        def timed(owner: object, attr: str, name: str) -> None:
            inner = getattr(owner, attr)
            spent[name] = 0.0

            def wrapper(*args: object) -> object:
                t0 = clock()
                out = inner(*args)
                spent[name] += clock() - t0
                return out

            setattr(owner, attr, wrapper)

        fdm = flight.fdm
        assert isinstance(fdm, JSBSimModel)
        timed(fdm, "step", "flight model (JSBSimModel.step: commands, frame, reads)")
        timed(fdm, "_run", "  JSBSim FGFDMExec.run()")
        timed(fdm, "_build_state", "  property reads -> VehicleState (truth)")
        timed(flight.sensors, "sample", "sensors: IMU, AHRS, GNSS")
        if flight.nav is not None:
            timed(flight.nav, "update", "onboard EKF (OnboardNav.update)")
            timed(flight.nav.filter, "predict", "  IMU summing, predictions (50 Hz)")
            for what in ("fuse_gnss", "fuse_baro", "fuse_heading", "fuse_airspeed"):
                timed(flight.nav.filter, what, f"  measurements in: {what[5:]}")
            timed(flight.nav.filter, "estimate", "  estimate out (50 Hz)")
            timed(flight.nav, "observe", "EKF scoring (OnboardNav.observe)")
        timed(flight.autopilot, "update", "autopilot")
        timed(flight.autopilot, "_guidance", "  guidance + sequencer (50 Hz)")
        timed(flight.autopilot._controller, "update", "  controller (200 Hz)")
        assert flight.battery is not None
        timed(flight.battery, "step", "battery")
        timed(flight.stats, "add", "summary statistics (FlightStats.add)")
        timed(writer, "on_sample", "trajectory.csv (rows at 50 Hz)")
        steps = int(seconds * 200)
        c0, w0 = time.process_time(), clock()
        for _ in range(steps):
            flight.step()
        cpu_us = (time.process_time() - c0) / steps * 1e6
        wall = clock() - w0
        top = sum(v for k, v in spent.items() if not k.startswith(" "))
        spent["rest of Flight.step (SimSample, camera tick, clock, wrappers)"] = wall - top
    to_cpu = cpu_us / (wall / steps * 1e6)
    return cpu_us, [(k, v / steps * 1e6 * to_cpu) for k, v in spent.items()]


def paired_cost(setup: FlightSetup, steps: int) -> tuple[float, float, float, int]:
    """The filter's cost per step from a truth and an ekf flight stepped in alternating
    chunks: (median, 25 %, 75 % of the chunk differences in us CPU, number of pairs)."""
    flights = {
        nav: build_flight(replace(setup, options=replace(setup.options, nav=nav)))
        for nav in ("truth", "ekf")
    }
    for flight in flights.values():  # past the filter's alignment and first compiled calls
        for _ in range(2 * CHUNK):
            flight.step()
    diffs = []
    for k in range(steps // CHUNK):
        cpu = {}
        for nav in ("truth", "ekf") if k % 2 == 0 else ("ekf", "truth"):
            flight = flights[nav]
            c0 = time.process_time()
            for _ in range(CHUNK):
                flight.step()
            cpu[nav] = (time.process_time() - c0) / CHUNK * 1e6
        diffs.append(cpu["ekf"] - cpu["truth"])
    q1, median, q3 = statistics.quantiles(diffs, n=4)
    return median, q1, q3, len(diffs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default="FR-300")
    parser.add_argument("--repeat", type=int, default=2, help="whole flights of each kind")
    parser.add_argument("--dem", default=None, help="also fly over this relief (builtin, FILE)")
    parser.add_argument("--paired-seconds", type=float, default=0.0)
    parser.add_argument("--parts-seconds", type=float, default=0.0, help="where a step goes")
    args = parser.parse_args()
    plan = REPO / "missions" / f"{args.scenario}.plan"
    setup = load_setup(plan, FlightOptions(nav="ekf"))
    load0 = os.getloadavg()[0]

    floor_us = bare_frame_s(setup) * 1e6
    kinds: dict[str, tuple[str, ...]] = {"ekf": (), "truth": ("--nav", "truth")}
    if args.dem:
        kinds["truth --dem"] = ("--nav", "truth", "--dem", args.dem)
    for extra in kinds.values():  # byte code and numba's cache in place, as after a first run
        fly_cpu(plan, *extra, "--max-sim-time", "0.1")
    whole: dict[str, list[tuple[float, int]]] = {k: [] for k in kinds}
    start: dict[str, list[tuple[float, int]]] = {k: [] for k in kinds}
    for _ in range(args.repeat):
        for kind, extra in kinds.items():
            whole[kind].append(fly_cpu(plan, *extra))
            start[kind].append(fly_cpu(plan, *extra, "--max-sim-time", "2"))
    bare_python = min(python_pass_cpu() for _ in range(3))
    # The floor again after the flights, the lower kept: a busy spell at the start of the run
    # would otherwise make every ratio look better than it is.
    floor_us = min(floor_us, bare_frame_s(setup) * 1e6)

    steps = whole["ekf"][0][1]
    print(
        f"scenario {args.scenario}, {steps} physics steps of 5 ms "
        f"({steps * PHYSICS_STEP_NS / NS_PER_S:.0f} s simulated), best of {args.repeat}, "
        f"load {load0:.1f} -> {os.getloadavg()[0]:.1f}"
    )
    print(f"{'what':44s} {'figure':>14s} {'floor':>12s} {'ratio':>7s} {'target':>7s}")
    print(f"{'bare FGFDMExec.run() in the air (floor)':44s} {floor_us:11.2f} us {'':12s}")
    targets = {"ekf": 4.0, "truth": 3.0}
    for kind in kinds:
        cpu_whole, n_whole = min(whole[kind])
        cpu_start, n_start = min(start[kind])
        per_step_us = (cpu_whole - cpu_start) / (n_whole - n_start) * 1e6
        ratio = per_step_us / floor_us
        target = targets.get(kind)
        mark = "" if target is None else f"{target:g}x " + ("met" if ratio <= target else "NOT")
        name = f"fly --no-camera --nav {kind}, per step"
        print(f"{name:44s} {per_step_us:11.2f} us {floor_us:9.2f} us {ratio:6.2f}x {mark}")
    for kind in kinds:
        cpu_start = min(start[kind])[0]
        name = f"start-up: a 2 s flight, --nav {kind}"
        mark = "1 s " + ("met" if cpu_start <= 1.0 else "NOT")
        print(
            f"{name:44s} {cpu_start:12.2f} s {bare_python:10.3f} s "
            f"{cpu_start / bare_python:6.1f}x {mark}  (floor: python -c pass)"
        )
    if args.parts_seconds > 0:
        for nav in ("ekf", "truth"):
            cpu_us, parts = step_parts(setup, nav, args.parts_seconds)
            ratio = cpu_us / floor_us
            print(
                f"where a step goes, --nav {nav}: {cpu_us:.1f} us CPU per step in all "
                f"({ratio:.1f}x the floor); its parts, us CPU per step:"
            )
            for name, us in parts:
                print(f"  {name:62s} {us:7.2f} us")
    if args.paired_seconds > 0:
        cost, low, high, pairs = paired_cost(setup, int(args.paired_seconds * 200))
        print(
            f"EKF cost, paired chunks: median {cost:.1f} us/step CPU (IQR {low:.1f}-{high:.1f}, "
            f"{pairs} pairs of {CHUNK} steps)"
        )


if __name__ == "__main__":
    main()
