"""Speed of the flight model and the controller, beside a bare JSBSim loop measured in the same run.

Prints steps per second, microseconds per step and the real-time ratio at the 200 Hz physics
rate for: a bare ``FGFDMExec.run()`` loop (the floor: JSBSim itself), ``JSBSimModel.step``
(plus building the VehicleState), and ``JSBSimModel.step`` + ``Controller.update`` in CRUISE.

    python benchmarks/bench_fdm.py [--seconds 60] [--aircraft airsitl_uav] [--repeats 3]
"""

from __future__ import annotations

import argparse
import time

from air_sitl.autopilot.control import Controller, gains_for
from air_sitl.autopilot.target import ControlPhase, ControlTarget
from air_sitl.clock import NS_PER_S, PHYSICS_STEP_NS
from air_sitl.fdm.base import InitialCondition, Wind
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=47.3977, lon_deg=8.5456, alt_amsl_m=488.0)


def _air_start(model: JSBSimModel, airspeed_m_s: float) -> None:
    ic = InitialCondition(
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=HOME.alt_amsl_m + 200.0,
        heading_rad=0.3,
        airspeed_m_s=airspeed_m_s,
        on_ground=False,
    )
    model.reset(HOME, ic, Wind(speed_m_s=3.0, from_deg=250.0))


def bench_floor(model: JSBSimModel, steps: int) -> float:
    """Seconds for ``steps`` bare JSBSim frames of the same loaded, trimmed model."""
    run = model._fdm.run  # the floor: JSBSim's own frame, no property reads, no Python state
    start = time.perf_counter()
    for _ in range(steps):
        run()
    return time.perf_counter() - start


def bench_model(model: JSBSimModel, steps: int) -> float:
    command = model.trim_command
    step = model.step
    start = time.perf_counter()
    for _ in range(steps):
        step(command)
    return time.perf_counter() - start


def bench_model_and_controller(model: JSBSimModel, aircraft: str, steps: int, v: float) -> float:
    controller = Controller(gains_for(aircraft), trim=model.trim_command)
    state = model.step(model.trim_command)
    target = ControlTarget(
        phase=ControlPhase.CRUISE,
        roll_rad=0.3,
        altitude_amsl_m=state.alt_amsl_m + 10.0,
        airspeed_m_s=v,
    )
    step = model.step
    update = controller.update
    start = time.perf_counter()
    for _ in range(steps):
        state = step(update(state, target))
    return time.perf_counter() - start


def main(seconds: float, aircraft: str, repeats: int) -> None:
    steps = int(seconds * NS_PER_S // PHYSICS_STEP_NS)
    airspeed = gains_for(aircraft).ref_airspeed_m_s
    model = JSBSimModel(aircraft)
    rows = []
    for name, fn in (
        ("bare FGFDMExec.run (floor)", lambda: bench_floor(model, steps)),
        ("JSBSimModel.step", lambda: bench_model(model, steps)),
        (
            "JSBSimModel.step + Controller.update",
            lambda: bench_model_and_controller(model, aircraft, steps, airspeed),
        ),
    ):
        # Best of a few runs: the machine is shared, the minimum is the cost of the code.
        best = float("inf")
        for _ in range(repeats):
            _air_start(model, airspeed)
            best = min(best, fn())
        rows.append((name, best))
    floor = rows[0][1]
    print(
        f"aircraft {aircraft}, {steps} steps of {PHYSICS_STEP_NS / 1e6:g} ms ({seconds:g} s), "
        f"best of {repeats}"
    )
    print(f"{'loop':40s} {'steps/s':>10s} {'us/step':>8s} {'x real time':>12s} {'x floor':>8s}")
    for name, elapsed in rows:
        per_step_us = elapsed / steps * 1e6
        realtime = seconds / elapsed
        print(
            f"{name:40s} {steps / elapsed:10.0f} {per_step_us:8.2f} {realtime:12.1f} "
            f"{elapsed / floor:8.2f}"
        )


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per loop")
    parser.add_argument("--aircraft", default="airsitl_uav")
    parser.add_argument("--repeats", type=int, default=3, help="runs per loop; the best counts")
    args = parser.parse_args()
    main(args.seconds, args.aircraft, args.repeats)
