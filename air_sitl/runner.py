"""Wires one vehicle together and runs it: clock -> flight model -> autopilot -> sensors -> sinks.

One thread (the caller of :meth:`Flight.run`) owns all simulation state. Other threads talk to
it only through ``inbox``: a queue of callables that run on the simulation thread between
physics steps (the MAVLink endpoint posts its commands there).
"""

from __future__ import annotations

import math
import queue
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

from air_sitl.autopilot.autopilot import Autopilot, air_start_pose
from air_sitl.autopilot.control import Controller, gains_for
from air_sitl.autopilot.params import ParamStore
from air_sitl.battery import Battery
from air_sitl.clock import CAMERA_PERIOD_NS, NS_PER_S, PHYSICS_STEP_NS, Pacer, SimClock
from air_sitl.errors import PlanError
from air_sitl.fdm.base import FlightModel, InitialCondition, Terrain
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.flightlog import FlightStats
from air_sitl.frames import geodetic2ned
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.nav.onboard import SCORE_PERIOD_NS, OnboardNav, denied_s, truth_nav_summary
from air_sitl.nav.params import NavParams
from air_sitl.options import DEFAULT_AIRCRAFT, FlightOptions
from air_sitl.sensors import SensorNoise, SensorSuite
from air_sitl.sinks import FlightResult, FrameSource, Sink
from air_sitl.state import (
    CameraTick,
    GeoPoint,
    SimSample,
    VehicleState,
    camera_tick,
    sim_sample,
)

InboxItem = Callable[["Flight"], None]
ProgressFn = Callable[[SimSample, "Flight"], None]


@dataclass(slots=True)
class FlightCounters:
    """What happened so far, for progress displays and summaries."""

    steps: int = 0
    frames_submitted: int = 0
    frames_delivered: int = 0
    capture_ticks: int = 0  # camera ticks inside the capture window (the archive's frames)
    camera_ticks: int = 0  # every camera tick (outside the window too when the camera stays on)


@dataclass(slots=True)
class Flight:
    """One simulated vehicle and everything that consumes its output."""

    fdm: FlightModel
    autopilot: Autopilot
    sensors: SensorSuite
    sinks: Sequence[Sink] = ()
    camera: FrameSource | None = None
    pacer: Pacer = field(default_factory=lambda: Pacer(0.0))
    # Capture frames with a lower index are counted but not rendered (resume of an archive).
    first_frame_to_render: int = 0
    # With an aid (--nav-aid) the camera runs for the whole flight: the aid's localizer needs
    # frames before and after the capture window too (only the window's frames are archived).
    # Without, the camera runs inside the capture window only.
    keep_camera_on: bool = False
    stats: FlightStats = field(default_factory=lambda: FlightStats(0))
    counters: FlightCounters = field(default_factory=FlightCounters)
    clock: SimClock = field(default_factory=lambda: SimClock(PHYSICS_STEP_NS))
    state: VehicleState | None = None
    last_sample: SimSample | None = None
    # The onboard filter the autopilot steers on (--nav ekf); None: it steers on the truth.
    nav: OnboardNav | None = None
    battery: Battery | None = None  # the propulsion battery (truth in: throttle flown)
    # Called once when the flight ends, after the sinks (the files a terrain model reads).
    on_close: Sequence[Callable[[], None]] = ()

    def step(self) -> SimSample:
        """Run one physics step: sensors, navigation, autopilot, sinks, camera, flight model."""
        state = self.state
        assert state is not None, "a Flight needs its initial state (see assemble_flight)"
        imu, gps = self.sensors.sample(state)
        nav = self.nav
        t_ns = state.sim_time_ns
        if nav is None:
            command, status = self.autopilot.update(state)
        else:
            command, status = self.autopilot.update(nav.update(state, imu, gps))
            if not t_ns % SCORE_PERIOD_NS:  # observe's own test, without its call (200 Hz)
                nav.observe(state, status)
        battery = None
        if self.battery is not None:
            battery = self.battery.step(t_ns, command.throttle)
        tick = None if t_ns % CAMERA_PERIOD_NS else self._camera_tick(status.capturing)
        sample = sim_sample(  # positional, in SimSample's field order (a 200 Hz path)
            state,
            status,
            imu,
            gps,
            nav.estimate if nav is not None else None,
            command,
            battery,
            tick,
        )
        self.stats.add(sample)
        for sink in self.sinks:
            sink.on_sample(sample)
        camera = self.camera
        if tick is not None:
            resumed = tick.capture_index is not None and (
                tick.capture_index < self.first_frame_to_render
            )
            if camera is not None and not resumed:
                camera.submit(sample, tick.index)
                self.counters.frames_submitted += 1
            if nav is not None:
                nav.frames_submitted = self.counters.camera_ticks
        if camera is not None:
            self._deliver(camera.ready())
        self.last_sample = sample
        self.state = self.fdm.step(command)
        clock = self.clock  # clock.tick() written out (a 200 Hz path)
        clock.now_ns += clock.step_ns
        self.counters.steps += 1
        return sample

    def _camera_tick(self, capturing: bool) -> CameraTick | None:
        """The camera exposure at a 50 Hz tick (the caller's test), if any: every tick inside
        the capture window, or of the whole flight when the camera stays on
        (:attr:`keep_camera_on`). The one home of the frame indices every sink sees
        (``SimSample.camera``)."""
        c = self.counters
        capture_index: int | None = None
        if capturing:
            capture_index = c.capture_ticks
            c.capture_ticks += 1
        elif not self.keep_camera_on:
            return None
        c.camera_ticks += 1
        return camera_tick(c.camera_ticks - 1, capture_index)  # positional: index, capture

    def _deliver(self, frames: Iterable[object]) -> None:
        for frame in frames:
            for sink in self.sinks:
                sink.on_frame(frame)  # type: ignore[arg-type]
            self.counters.frames_delivered += 1

    def run(
        self,
        *,
        stop: Callable[[SimSample], bool],
        max_sim_time_ns: int,
        inbox: queue.SimpleQueue[InboxItem] | None = None,
        progress: ProgressFn | None = None,
        progress_period_ns: int = NS_PER_S,
    ) -> FlightResult:
        """Step until ``stop(sample)`` is true or ``max_sim_time_ns`` passes; close every sink.

        Sinks are closed even when a sink or the model raises, so what was written stays valid.
        """
        wall_start = time.monotonic()
        pacer = self.pacer
        try:
            while True:
                if inbox is not None:
                    while True:
                        try:
                            item = inbox.get_nowait()
                        except queue.Empty:
                            break
                        item(self)
                sample = self.step()
                t = sample.state.sim_time_ns
                if progress is not None and t % progress_period_ns == 0:
                    progress(sample, self)
                if pacer.speed != 0.0:  # as fast as possible: wait() would return at once
                    pacer.wait(t)
                if stop(sample):
                    break
                if t >= max_sim_time_ns:
                    break
            if self.camera is not None:
                self._deliver(self.camera.flush())
        finally:
            wall = time.monotonic() - wall_start
            summary = self.stats.summary(wall)
            if self.nav is not None:
                summary.update(self.nav.summary())
                nav_block = summary["nav"]  # denied by the windows, or GNSS lost otherwise
                nav_block["gnss_denied_s"] = max(
                    nav_block["gnss_denied_s"],
                    denied_s(self.sensors.gps_denied_ns, self.stats.sim_time_ns),
                )
            else:
                summary.update(truth_nav_summary(summary, self.sensors, self.stats.sim_time_ns))
            result = FlightResult(
                mission_completed=self.stats.mission_completed,
                sim_time_ns=self.stats.sim_time_ns,
                wall_time_s=wall,
                summary=summary,
            )
            if self.camera is not None:
                self.camera.close()
            for sink in self.sinks:
                sink.close(result)
            for close in self.on_close:
                close()
        return result


def ground_start_heading_rad(mission: Mission, home: GeoPoint) -> float:
    """Heading of a ground start: toward the first positioned item away from home."""
    for item in mission.items:
        if not item.is_nav or item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            continue
        if item.lat_deg == 0.0 and item.lon_deg == 0.0:
            continue
        n, e, _ = geodetic2ned(
            item.lat_deg, item.lon_deg, home.alt_amsl_m, home.lat_deg, home.lon_deg, home.alt_amsl_m
        )
        if math.hypot(n, e) > 1.0:
            return math.atan2(e, n)
    return 0.0


def home_of(mission: Mission) -> GeoPoint:
    """The planned home of a mission (where the vehicle starts on the ground)."""
    if mission.planned_home is not None:
        return mission.planned_home
    for item in mission.items:
        if item.is_nav and not (item.lat_deg == 0.0 and item.lon_deg == 0.0):
            return GeoPoint(lat_deg=item.lat_deg, lon_deg=item.lon_deg, alt_amsl_m=0.0)
    msg = f"{mission.source}: the plan has no planned home and no positioned item"
    raise PlanError(msg)


def assemble_flight(
    mission: Mission,
    options: FlightOptions,
    *,
    sinks: Sequence[Sink] = (),
    camera: FrameSource | None = None,
    home: GeoPoint | None = None,
    auto_start: bool = True,
    terrain: Terrain | None = None,
) -> tuple[Flight, GeoPoint, InitialCondition]:
    """Build the flight model, autopilot and sensors (GNSS denial included) and place the aircraft.

    ``auto_start=False`` (serve): the vehicle waits on the ground, disarmed, for a client.
    ``terrain`` (``--dem``): the ground under the flight; home must be on it.
    """
    home = home or home_of(mission)
    gains = gains_for(options.aircraft)
    # Our UAV's parameter defaults; other aircraft fly inside their own speed envelope.
    overrides: dict[str, float] = {}
    if options.aircraft != DEFAULT_AIRCRAFT:
        overrides.update(
            FW_AIRSPD_TRIM=gains.ref_airspeed_m_s,
            FW_AIRSPD_MIN=gains.min_airspeed_m_s,
            FW_AIRSPD_MAX=gains.max_airspeed_m_s,
        )
    if options.nav_aid == "mavlink":
        overrides["EKF2_EV_CTRL"] = 1  # horizontal position from external vision
    if options.nav_aid_sigma_m != FlightOptions().nav_aid_sigma_m:
        overrides["EKF2_EVP_NOISE"] = options.nav_aid_sigma_m
    params = ParamStore(overrides or None)
    surface = terrain.height_at if terrain is not None else None
    if options.air_start:
        lat, lon, alt, heading, airspeed = air_start_pose(mission, home, params, surface)
        initial = InitialCondition(
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt,
            heading_rad=heading,
            airspeed_m_s=airspeed,
            on_ground=False,
        )
    else:
        initial = InitialCondition(
            lat_deg=home.lat_deg,
            lon_deg=home.lon_deg,
            alt_amsl_m=home.alt_amsl_m,
            heading_rad=ground_start_heading_rad(mission, home),
        )
    fdm = JSBSimModel(aircraft=options.aircraft, seed=options.seed, terrain=terrain)
    state0 = fdm.reset(home, initial, options.wind)
    # Airborne: start the controller's integrators at the trimmed controls, so any aircraft
    # (not only ours, whose default gains hold its trim) begins steady.
    trim = fdm.trim_command if options.air_start else None
    autopilot = Autopilot(
        mission,
        home,
        params,
        Controller(gains, trim=trim),
        air_start=options.air_start,
        auto_start=auto_start,
        surface=surface,
    )
    noise = SensorNoise().scaled(options.sensor_noise)
    sensors = SensorSuite(
        home,
        seed=options.seed,
        step_ns=fdm.step_ns,
        noise=noise,
        gps_denied_ns=options.gps_denied_ns,
    )
    nav = None
    if options.nav == "ekf":
        nav = OnboardNav(
            home,
            seed=options.seed,
            noise_scale=options.sensor_noise,
            params=NavParams(aid_sigma_m=options.nav_aid_sigma_m),
            gps_denied=sensors.gps_denied,
            aid_name=options.nav_aid,
        )
        nav.autopilot = autopilot
    flight = Flight(
        nav=nav,
        fdm=fdm,
        autopilot=autopilot,
        sensors=sensors,
        sinks=sinks,
        camera=camera,
        pacer=Pacer(options.speed),
        stats=FlightStats(
            sum(1 for item in mission.items if item.is_nav),
            landing_items=frozenset(
                i for i, item in enumerate(mission.items) if item.command == MavCmd.NAV_LAND
            ),
        ),
        clock=SimClock(fdm.step_ns),
        state=state0,
        battery=Battery.following(params),
        keep_camera_on=options.nav_aid is not None,
    )
    return flight, home, initial
