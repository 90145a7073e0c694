"""Speed of the flight core: flight model + autopilot + sensors (+ the onboard EKF), against bare
JSBSim.

Usage: python benchmarks/bench_flight.py [SCENARIO] [--seconds 600] [--repeat 3]
[--dem builtin|FILE]

Flies SCENARIO (default FR-300) with --air-start and no camera for --seconds of simulated time
and prints simulated seconds per wall second, beside the floor measured in the same run: the
bare flight model stepping the same number of times with a fixed command. The flight runs
on the truth (--nav truth) and on the onboard filter (--nav ekf, the default of the commands),
--repeat times each, alternated, the best of each kept: the difference per step is what the
filter costs. As whole flights are at the mercy of whatever else the machine does for seconds
at a time, the two flights are then also stepped side by side in chunks of 500 steps
(alternating which goes first) and the median of the chunk-pair differences is printed: the
figure a busy machine moves least. ``--dem`` adds
a truth flight over that relief (ground and surface sampled at every step, home on the
ground): its difference is what the relief costs the flight.
"""

from __future__ import annotations

import argparse
import statistics
import time
from dataclasses import replace
from pathlib import Path

from air_sitl.builder import FlightSetup, build_flight, load_setup
from air_sitl.clock import NS_PER_S
from air_sitl.options import FlightOptions, MapChoice
from air_sitl.state import ActuatorCommand

REPO = Path(__file__).resolve().parent.parent


CHUNK = 500  # physics steps a flight runs before the other takes its turn


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
    parser.add_argument("--seconds", type=float, default=600.0)
    parser.add_argument("--dem", default=None, help="also fly over this relief (builtin, FILE)")
    parser.add_argument(
        "--repeat", type=int, default=3, help="whole flights of each kind, alternated (best kept)"
    )
    args = parser.parse_args()
    setup = load_setup(REPO / "missions" / f"{args.scenario}.plan", FlightOptions(air_start=True))
    limit_ns = int(args.seconds * NS_PER_S)

    def fly(nav: str, over: FlightSetup | None = None) -> tuple[float, float, int, int]:
        base = over or setup
        flight = build_flight(replace(base, options=replace(base.options, nav=nav)))
        t0, c0 = time.perf_counter(), time.process_time()
        result = flight.run(stop=lambda s: False, max_sim_time_ns=limit_ns)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        return wall, cpu, flight.counters.steps, result.sim_time_ns

    # Alternated, best of --repeat each: the machine is shared, the filter's cost is a
    # difference, and a slow spell of the machine only ever adds time.
    runs = [fly(nav) for _ in range(args.repeat) for nav in ("truth", "ekf")]
    full, cpu = min(r[0] for r in runs[::2]), min(r[1] for r in runs[::2])
    full_ekf, cpu_ekf = min(r[0] for r in runs[1::2]), min(r[1] for r in runs[1::2])
    steps, sim_ns = runs[0][2], runs[0][3]

    bare = build_flight(setup)
    command = ActuatorCommand(throttle=0.5)
    t0 = time.perf_counter()
    for _ in range(steps):
        bare.fdm.step(command)
    floor = time.perf_counter() - t0

    sim_s = sim_ns / NS_PER_S
    print(f"scenario {args.scenario}, {sim_s:.0f} s simulated, {steps} physics steps at 200 Hz")
    print(f"bare flight model step   {floor / steps * 1e6:7.1f} us/step  {sim_s / floor:7.0f} x rt")
    print(f"model+autopilot+sensors  {full / steps * 1e6:7.1f} us/step  {sim_s / full:7.0f} x rt")
    print(
        f"same + onboard EKF       {full_ekf / steps * 1e6:7.1f} us/step  "
        f"{sim_s / full_ekf:7.0f} x rt"
    )
    print(f"ratio full / bare model  {full / floor:7.2f}")
    print(
        f"EKF cost {(full_ekf - full) / steps * 1e6:.1f} us/step wall, "
        f"{(cpu_ekf - cpu) / steps * 1e6:.1f} us/step CPU (target <= 15); "
        f"ratio with / without {full_ekf / full:.2f} wall, {cpu_ekf / cpu:.2f} CPU"
    )
    print(f"target: >= 100 x real time -> {'met' if sim_s / full >= 100 else 'NOT met'}")
    cost, low, high, pairs = paired_cost(setup, steps)
    print(
        f"EKF cost, paired chunks: median {cost:.1f} us/step CPU (IQR {low:.1f}-{high:.1f}, "
        f"{pairs} pairs of {CHUNK} steps; target <= 15)"
    )
    if args.dem:
        plan = REPO / "missions" / f"{args.scenario}.plan"
        relief = load_setup(plan, FlightOptions(air_start=True), map=MapChoice(dem=args.dem))
        runs_dem = [fly("truth", relief) for _ in range(2)]
        cpu_dem = min(r[1] for r in runs_dem)
        print(
            f"--dem {args.dem}: {min(r[0] for r in runs_dem) / steps * 1e6:.1f} us/step wall, "
            f"relief cost {(cpu_dem - cpu) / steps * 1e6:.1f} us/step CPU "
            f"(ratio {cpu_dem / cpu:.2f} CPU)"
        )


if __name__ == "__main__":
    main()
