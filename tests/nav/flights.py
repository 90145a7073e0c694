"""Recorded flights for the navigation tests: truth, IMU and GNSS of real JSBSim flights.

The only place that touches the runner (read-only, through ``assemble_flight`` and
``Flight.step``): if its API moves, this is the one function to adapt. Flights are cached
per (plan, seconds, wind, seed) for the test session.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

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


@functools.lru_cache(maxsize=8)
def record(
    plan: str = "UC-200", seconds: float = 180.0, wind: tuple[float, float] = (5.0, 270.0),
    seed: int = 1,
) -> Recording:
    """Fly ``plan`` from an air start for ``seconds`` and keep every 5 ms step."""
    from air_sitl.fdm.base import Wind
    from air_sitl.mission.plan_file import load_mission
    from air_sitl.options import FlightOptions
    from air_sitl.runner import assemble_flight

    mission = load_mission(MISSIONS / f"{plan}.plan")
    options = FlightOptions(
        air_start=True, wind=Wind(speed_m_s=wind[0], from_deg=wind[1]), seed=seed
    )
    flight, home, _ = assemble_flight(mission, options)
    baro = Barometer(seed=seed)
    airspeed = AirspeedSensor(seed=seed)
    mag = Magnetometer(seed=seed)
    steps = []
    n = round(seconds * 200)
    for _ in range(n):
        s = flight.step()
        st = s.state
        steps.append(Step(st, s.imu, s.gps, baro.sample(st), airspeed.sample(st), mag.sample(st)))
    return Recording(home, tuple(steps))


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


def enu_aid(name: str, t_ns: int, north: float, east: float, up: float = 0.0,
            sigma: float | None = None) -> AidMeasurement:
    return AidMeasurement(name=name, sim_time_ns=t_ns, position=(east, north, up), sigma_m=sigma)


def run(rec: Recording, params: NavParams | None = None, *, deny_after_s: float | None = None):
    """Fly the filter over a recording; yields (step, nav) after each step."""
    nav = NavFilter(rec.home, params)
    for step in rec.steps:
        t = step.imu.sim_time_ns - rec.steps[0].imu.sim_time_ns
        gnss = deny_after_s is None or t < deny_after_s * NS
        feed(nav, step, gnss=gnss)
        yield step, nav
