"""The real endpoint and a real flight in this process, with the truth recorded for comparison."""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field

from air_sitl.clock import NS_PER_S
from air_sitl.mavlink.links import parse_link
from air_sitl.mavlink.nav_aid import NavLink
from air_sitl.mavlink.vehicle import EndpointOptions, Job, VehicleEndpoint
from air_sitl.mission.items import Mission
from air_sitl.options import OPEN_END_NS, FlightOptions
from air_sitl.runner import Flight, InboxItem, assemble_flight
from air_sitl.sinks import NullSink
from air_sitl.state import FlightMode, GeoPoint, SimSample, VehicleState


class TruthSink(NullSink):
    """Every truth state by simulated millisecond, and every flight mode the autopilot was in
    (in order, however briefly: the wall-clock heartbeat can miss a mode that lasts less than a
    second of wall time). ``listeners`` are called with each state on the simulation thread:
    a test's peer that must follow simulated time (a companion computer) rides on them."""

    def __init__(self) -> None:
        self.by_ms: dict[int, VehicleState] = {}
        self.states: list[VehicleState] = []
        self.modes: list[FlightMode] = []
        self.listeners: list[Callable[[VehicleState], None]] = []

    def on_sample(self, sample: SimSample) -> None:
        self.by_ms[sample.state.sim_time_ns // 1_000_000] = sample.state
        self.states.append(sample.state)
        for listener in tuple(self.listeners):
            listener(sample.state)
        mode = sample.autopilot.mode
        if not self.modes or self.modes[-1] is not mode:
            self.modes.append(mode)


@dataclass
class Vehicle:
    """A running vehicle: endpoint, flight and its simulation thread."""

    endpoint: VehicleEndpoint
    flight: Flight
    truth: TruthSink
    stop: threading.Event = field(default_factory=threading.Event)
    thread: threading.Thread | None = None


@contextlib.contextmanager
def running_vehicle(
    links: Sequence[str],
    home: GeoPoint,
    *,
    speed: float,
    mission: Mission | None = None,
    options: EndpointOptions | None = None,
    aided_denied_after_s: float | None = None,
) -> Iterator[Vehicle]:
    """Serve a vehicle on ``links`` until the block ends. ``aided_denied_after_s``: the flight
    steers on the onboard filter, aided over MAVLink, with no GNSS from this simulated second
    (``serve --nav ekf --nav-aid mavlink --gps-denied-after S``)."""
    mission = mission or Mission(items=(), source="test")
    inbox: queue.SimpleQueue[InboxItem] = queue.SimpleQueue()

    def post(job: Job) -> None:
        inbox.put(lambda flight: job(flight.autopilot))

    endpoint = VehicleEndpoint(
        [parse_link(u) for u in links], home=home, mission=mission, post=post, options=options
    )
    endpoint.open()
    truth = TruthSink()
    if aided_denied_after_s is None:
        flight_options, aid_sinks = FlightOptions(speed=speed), []
    else:
        denied_ns = ((round(aided_denied_after_s * NS_PER_S), OPEN_END_NS),)
        flight_options = FlightOptions(
            speed=speed, nav="ekf", nav_aid="mavlink", gps_denied_ns=denied_ns
        )
        aid_sinks = [NavLink(endpoint, aid=True)]
    flight, _home, _ = assemble_flight(
        mission,
        flight_options,
        sinks=[endpoint.sink, *aid_sinks, truth],
        home=home,
        auto_start=False,
    )
    for nav_link in aid_sinks:
        assert flight.nav is not None
        nav_link.attach(flight.nav, flight.autopilot.params)
    endpoint.attach(flight.autopilot, flight.autopilot.params)
    endpoint.start()
    vehicle = Vehicle(endpoint, flight, truth)
    thread = threading.Thread(
        target=flight.run,
        kwargs={
            "stop": lambda _s: vehicle.stop.is_set(),
            "max_sim_time_ns": 10**15,
            "inbox": inbox,
        },
        daemon=True,
    )
    vehicle.thread = thread
    thread.start()
    try:
        yield vehicle
    finally:
        vehicle.stop.set()
        thread.join(timeout=10)
        endpoint.close()
