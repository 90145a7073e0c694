"""Recorded flights for the navigation tests: truth, IMU and GNSS of real JSBSim flights.

The only place that touches the runner (read-only, through ``assemble_flight`` and
``Flight.step``): if its API moves, this is the one function to adapt. Flights are cached
per (plan, wind, seed) for the test session: a shorter one is the start of a longer one.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from air_sitl.nav import AidMeasurement, NavFilter, NavParams
from air_sitl.nav.sensors_extra import AirspeedSensor, Barometer, Magnetometer
from air_sitl.nav.types import AirspeedSample, BaroSample, HeadingSample
from air_sitl.state import GeoPoint, GpsFix, ImuSample, VehicleState

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
NS = 1_000_000_000


@dataclass(frozen=True, slots=True)
class Step:
    state: VehicleState
    imu: ImuSample
    gps: GpsFix | None
    baro: BaroSample | None
    airspeed: AirspeedSample | None
    heading: HeadingSample | None


@dataclass(frozen=True, slots=True)
class Recording:
    home: GeoPoint
    steps: tuple[Step, ...]


def _build(path: Path, options: object) -> tuple[Any, GeoPoint]:
    """The flight and its home through whichever builder the tree has (the runner is being
    restructured: ``air_sitl.builder`` first, ``runner.assemble_flight`` as it was)."""
    try:
        from air_sitl.builder import build_flight, load_setup

        setup = load_setup(path, options)  # type: ignore[arg-type]
        return build_flight(setup), setup.home
    except (ImportError, TypeError, AttributeError):
        from air_sitl.mission.plan_file import load_mission
        from air_sitl.runner import assemble_flight

        flight, home, _ = assemble_flight(load_mission(path), options)  # type: ignore[arg-type]
        return flight, home


_RECORDED: dict[tuple[str, tuple[float, float], int], Recording] = {}


def record(
    plan: str = "UC-200",
    seconds: float = 180.0,
    wind: tuple[float, float] = (5.0, 270.0),
    seed: int = 1,
) -> Recording:
    """Fly ``plan`` from an air start for ``seconds`` and keep every 5 ms step.

    Cached: the first ``seconds`` of a longer flight already recorded are the same steps (one
    seed, the sensors drawn in the same order), so they are sliced from it."""
    n = round(seconds * 200)
    known = _RECORDED.get((plan, wind, seed))
    if known is not None and len(known.steps) >= n:
        return Recording(known.home, known.steps[:n])
    from air_sitl.fdm.base import Wind
    from air_sitl.options import FlightOptions

    options = FlightOptions(
        air_start=True, wind=Wind(speed_m_s=wind[0], from_deg=wind[1]), seed=seed
    )
    flight, home = _build(MISSIONS / f"{plan}.plan", options)
    baro = Barometer(seed=seed)
    airspeed = AirspeedSensor(seed=seed)
    mag = Magnetometer(seed=seed)
    steps = []
    for _ in range(n):
        s = flight.step()
        st = s.state
        steps.append(Step(st, s.imu, s.gps, baro.sample(st), airspeed.sample(st), mag.sample(st)))
    _RECORDED[plan, wind, seed] = recording = Recording(home, tuple(steps))
    return recording


def feed(nav: NavFilter, step: Step, *, gnss: bool = True) -> None:
    """One step's sensor readings into the filter, as the runner will (measurements first)."""
    t = step.imu.sim_time_ns
    if step.heading is not None:
        nav.fuse_heading(step.heading, t)
    if step.baro is not None:
        nav.fuse_baro(step.baro, t)
    if step.airspeed is not None:
        nav.fuse_airspeed(step.airspeed, t)
    if gnss and step.gps is not None:
        nav.fuse_gnss(step.gps, t)
    nav.predict(step.imu)


def horizontal_error(nav: NavFilter, state: VehicleState) -> float:
    est = nav.estimate()
    return math.hypot(est.pos_ned_m[0] - state.pos_ned_m[0], est.pos_ned_m[1] - state.pos_ned_m[1])


def enu_aid(
    name: str, t_ns: int, north: float, east: float, up: float = 0.0, sigma: float | None = None
) -> AidMeasurement:
    return AidMeasurement(name=name, sim_time_ns=t_ns, position=(east, north, up), sigma_m=sigma)


AidSource = Callable[[Step, float], Iterable[tuple[AidMeasurement, int]]]


@dataclass(frozen=True, slots=True)
class Point:
    """One traced instant: time from the start, estimate and truth (NED), horizontal std."""

    t_s: float
    est_ned_m: tuple[float, float, float]
    truth_ned_m: tuple[float, float, float]
    std_h_m: float
    cov_ne_m2: tuple[float, float, float]
    source: str

    @property
    def error_h_m(self) -> float:
        return math.hypot(
            self.est_ned_m[0] - self.truth_ned_m[0], self.est_ned_m[1] - self.truth_ned_m[1]
        )

    @property
    def error_ne_m(self) -> tuple[float, float]:
        return (self.est_ned_m[0] - self.truth_ned_m[0], self.est_ned_m[1] - self.truth_ned_m[1])


def fly(
    rec: Recording,
    params: NavParams | None = None,
    *,
    deny_after_s: float | None = None,
    deny_until_s: float = math.inf,
    aid: AidSource | None = None,
    until_s: float | None = None,
    trace_every: int = 20,
) -> tuple[NavFilter, list[Point]]:
    """Run the filter over ``rec``: GNSS cut from ``deny_after_s`` (to ``deny_until_s``), aid
    measurements from ``aid(step, t_s)`` fed before each step's prediction; trace every
    ``trace_every`` steps."""
    nav = NavFilter(rec.home, params)
    t0 = rec.steps[0].imu.sim_time_ns
    trace: list[Point] = []
    for i, step in enumerate(rec.steps):
        t_s = (step.imu.sim_time_ns - t0) / NS
        if until_s is not None and t_s > until_s:
            break
        if aid is not None:
            for m, now in aid(step, t_s):
                nav.fuse_aid(m, now)
        denied = deny_after_s is not None and deny_after_s <= t_s < deny_until_s
        feed(nav, step, gnss=not denied)
        if i % trace_every == 0:
            e = nav.estimate()
            trace.append(
                Point(
                    t_s,
                    e.pos_ned_m,
                    step.state.pos_ned_m,
                    e.std_h_m,
                    nav.horizontal_covariance(),
                    nav.status().source,
                )
            )
    return nav, trace


def at(trace: list[Point], t_s: float) -> Point:
    """The traced point nearest ``t_s``."""
    return min(trace, key=lambda p: abs(p.t_s - t_s))


def between(trace: list[Point], a_s: float, b_s: float) -> list[Point]:
    return [p for p in trace if a_s <= p.t_s < b_s]


def percentile(values: list[float], q: float) -> float:
    xs = sorted(values)
    k = min(len(xs) - 1, max(0, round(q / 100.0 * (len(xs) - 1))))
    return xs[k]
