"""The live view (``--foxglove``): a Sink that hands the flight to a Foxglove WebSocket server.

The simulation thread only copies references into a bounded queue (``put_nowait``; a full queue
drops the item and counts it, never waits), and only at the rates the view sends (the state at
``STATE_RATE_HZ``, images at ``--foxglove-image-hz``; each frame's truth position goes into a
ring the worker reads for the estimates' errors); a worker thread builds the messages with
:mod:`air_sitl.foxglove.topics` and logs them on a Context served by the SDK's server (and
written by its MCAP writer with ``--foxglove-mcap``). The SDK keeps a backlog per client and
drops the oldest for a slow one. A client subscribing later is sent the calibration, the
mission and the camera mount at once.
"""

from __future__ import annotations

import contextlib
import queue
import sys
import threading
import time
from collections import OrderedDict, deque
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import foxglove
from foxglove.messages import LogLevel
from foxglove.websocket import ChannelView, Client, ServerListener

from air_sitl.bus.codec import Estimate
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.errors import OptionError
from air_sitl.foxglove import topics as tp
from air_sitl.frames import geodetic2ned, ned2enu, ned2geodetic, q_frd_ned_to_flu_enu
from air_sitl.mission.items import Mission
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import (
    CameraFrame,
    GeoPoint,
    GpsFix,
    NavEstimate,
    Quat,
    SimSample,
    Vec3,
    VehicleState,
)

QUEUE_DEPTH = 2048  # items between the simulation and the worker (a minute of a flight)
STATE_RATE_HZ = 10.0  # truth/nav fixes, poses and /tf
TRUTH_KEPT = 4096  # truth positions kept by time for the estimates' errors (80 s at 50 Hz)
STOP_TIMEOUT_S = 10.0
# The server calls on_subscribe before the subscription may take effect: the latched messages
# go at once and again these long after (a client may get them more than once; on a loaded
# machine the subscription can take effect late, so the last pass waits seconds), then every
# LATCH_EVERY_S while the view runs: a subscription that took effect later still gets them.
LATCH_AGAIN_S = (0.2, 1.0, 3.0)
LATCH_EVERY_S = 5.0


@dataclass(frozen=True, slots=True, kw_only=True)
class LiveOptions:
    """Where the server listens, the image rate, an MCAP file to record the same into."""

    host: str
    port: int | None  # None: no server (only the MCAP file)
    image_hz: float
    mcap: Path | None = None


class _Listener(ServerListener):
    """The server's callbacks (its thread): a subscription asks for the latched messages."""

    def __init__(self, due: threading.Event) -> None:
        self.due = due

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.due.set()


class FoxgloveLive(NullSink):
    """Publishes one vehicle's flight on a Foxglove WebSocket server (see the module doc)."""

    def __init__(
        self,
        options: LiveOptions,
        *,
        vehicle: str,
        home: GeoPoint | None,
        camera: CameraModel | None,
        out: IO[str] = sys.stderr,
        queue_depth: int = QUEUE_DEPTH,
    ) -> None:
        self.options = options
        self.home = home
        self.camera = camera
        self.out = out
        self.context = foxglove.Context()
        self.channels = tp.Channels(self.context, vehicle)
        self._due = threading.Event()
        self._latch_again_s: list[float] = []  # monotonic times of the passes still due
        self._writer: Any = None
        if options.mcap is not None:
            if options.mcap.exists():
                msg = f"--foxglove-mcap: {options.mcap} exists already (nothing is overwritten)"
                raise OptionError(msg)
            self._writer = foxglove.open_mcap(options.mcap, context=self.context)
        self.server: Any = None
        self.port: int | None = None
        if options.port is not None:
            self._serve(options.host, options.port, vehicle)
        self._queue: queue.Queue[tuple[Any, ...] | None] = queue.Queue(maxsize=queue_depth)
        self.dropped = 0
        self.handled = 0  # updates the worker took
        self.failed: str | None = None
        self._mission: Mission | None = None
        self._image_period_ns = int(NS_PER_S / options.image_hz) if options.image_hz > 0 else 0
        self._state_period_ns = int(NS_PER_S / STATE_RATE_HZ)
        self._next_image_ns = 0
        self._next_state_ns = 0
        self._last_status: tuple[Any, ...] | None = None
        # Each frame's truth (time, NED position) from the simulation thread (an atomic append,
        # no lock); the worker moves them into _truth when it needs them.
        self._truth_in: deque[tuple[int, Vec3]] = deque(maxlen=TRUTH_KEPT)
        self._truth: OrderedDict[int, Vec3] = OrderedDict()
        self._estimators: dict[str, int] = {}
        self._closed = False
        self._now_ns = 0  # the latest sample's simulation time
        self._thread = threading.Thread(target=self._work, name="foxglove", daemon=True)
        self._thread.start()

    def _serve(self, host: str, port: int, vehicle: str) -> None:
        try:
            self.server = foxglove.start_server(
                name=f"air-sitl {vehicle}",
                host=host,
                port=port,
                context=self.context,
                server_listener=_Listener(self._due),
            )
        except Exception as err:  # the SDK's own error type
            if self._writer is not None:
                self._writer.close()
            msg = f"--foxglove {host}:{port}: cannot listen ({err})"
            raise OptionError(msg) from None
        self.port = int(self.server.port)
        print(f"foxglove: ws://{host}:{self.port} ({vehicle})", file=self.out, flush=True)

    # The simulation's side: references into the queue, nothing else.

    def _put(self, item: tuple[Any, ...]) -> None:
        try:
            self._queue.put_nowait(item)
        except queue.Full:
            self.dropped += 1

    def start(self, mission: Mission) -> None:
        """The mission as flown, or as a client uploaded it (the ``mission`` topic; latched
        for late clients)."""
        self._put(("mission", mission))

    def on_sample(self, sample: SimSample) -> None:
        t = sample.state.sim_time_ns
        self._now_ns = t
        if sample.gps is not None:
            self._put(("gnss", sample.gps))
        if t >= self._next_state_ns:
            self._next_state_ns = t + self._state_period_ns
            self._put(("state", sample.state, sample.nav))
        ap = sample.autopilot
        status = (ap.mode, ap.armed, ap.current_seq)
        if status != self._last_status:
            self._last_status = status
            self._put(("status", t, status))

    def on_frame(self, frame: CameraFrame) -> None:
        state = frame.sample.state  # the estimates' times are frames' times
        self._truth_in.append((state.sim_time_ns, state.pos_ned_m))
        if self._image_period_ns and frame.sim_time_ns >= self._next_image_ns:
            self._next_image_ns = frame.sim_time_ns + self._image_period_ns
            self._put(("image", frame.sim_time_ns, frame.jpeg, frame.sample.state))

    def on_image(self, sim_time_ns: int, jpeg: bytes) -> None:
        """A frame without its sample (camera-bridge: rendered from the bus's truth)."""
        if self._image_period_ns and sim_time_ns >= self._next_image_ns:
            self._next_image_ns = sim_time_ns + self._image_period_ns
            self._put(("image", sim_time_ns, jpeg, None))

    def on_estimate(
        self, name: str, frame: int | None, sim_time_ns: int | None, est: Estimate | None
    ) -> None:
        """An estimate from the bus (EstimateLog's listener, on the bus's thread)."""
        if est is not None and sim_time_ns is not None:
            self._put(("estimate", name, sim_time_ns, est))

    def statustext(self, sim_time_ns: int, text: str, severity: int) -> None:
        """A STATUSTEXT the vehicle sends (MAVLink severity 0 emergency .. 7 debug)."""
        self._put(("text", sim_time_ns, text, severity))

    def on_statustext(self, severity: int, text: str) -> None:
        """A STATUSTEXT the vehicle broadcasts (the endpoint's listener, its I/O thread),
        stamped with the latest simulation time."""
        self.statustext(self._now_ns, text, severity)

    def close(self, result: FlightResult | None = None) -> None:
        """Drain the queue, stop the server, report what was dropped (once)."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(queue.Full):
            self._queue.put(None, timeout=STOP_TIMEOUT_S)
        self._thread.join(STOP_TIMEOUT_S)
        self.channels.close()
        if self.server is not None:
            self.server.stop()
        if self._writer is not None:
            self._writer.close()
        if self.dropped:
            print(
                f"foxglove: {self.dropped} updates dropped (the view fell behind the flight)",
                file=self.out,
                flush=True,
            )
        if self.failed is not None:
            print(f"foxglove: stopped publishing: {self.failed}", file=self.out, flush=True)

    # The worker's side.

    def _work(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=0.1)
            except queue.Empty:
                item = ()
            if self._due.is_set():
                self._due.clear()
                self._latched()
                now = time.monotonic()
                self._latch_again_s = [now + after for after in LATCH_AGAIN_S]
            elif self._latch_again_s and time.monotonic() >= self._latch_again_s[0]:
                self._latch_again_s.pop(0)
                if not self._latch_again_s:
                    self._latch_again_s.append(time.monotonic() + LATCH_EVERY_S)
                self._latched()
            if item is None:
                return
            if not item or self.failed is not None:
                continue
            self.handled += 1
            try:
                self._handle(item)
            except Exception as err:  # a view fault must never stop the flight
                self.failed = f"{type(err).__name__}: {err}"

    def _take_truth(self) -> None:
        """Move the frames' truth from the simulation's ring into ``_truth`` (ENU by time)."""
        truth, ring = self._truth, self._truth_in
        while ring:
            t, pos_ned_m = ring.popleft()
            truth[t] = ned2enu(pos_ned_m)
        while len(truth) > TRUTH_KEPT:
            truth.popitem(last=False)

    def _latched(self) -> None:
        self._take_truth()
        t = next(reversed(self._truth), 0) if self._truth else 0
        if self.camera is not None:
            self.channels.log(tp.CALIBRATION, t, tp.calibration(t, self.camera))
            mount = foxglove.messages.FrameTransforms(transforms=[tp.camera_mount(t, self.camera)])
            self.channels.log(tp.TF_TOPIC, t, mount)
        if self._mission is not None:
            self.channels.log(tp.MISSION, t, tp.mission_geojson(self._mission))

    def _handle(self, item: tuple[Any, ...]) -> None:
        kind = item[0]
        ch = self.channels
        if kind == "image":
            _, t, jpeg, state = item
            ch.log(tp.IMAGE, t, tp.image(t, jpeg))
            if self.camera is not None:
                ch.log(tp.CALIBRATION, t, tp.calibration(t, self.camera))
            if self.camera is not None and state is not None and self.home is not None:
                enu, q = _enu_q(state)
                corners = tp.footprint_lonlat(self.camera, enu, q, state.alt_agl_m, self.home)
                if corners is not None:
                    ch.log(tp.FOOTPRINT, t, tp.footprint(corners))
        elif kind == "state":
            self._state(item[1], item[2])
        elif kind == "gnss":
            self._gnss(item[1])
        elif kind == "estimate":
            self._estimate(item[1], item[2], item[3])
        elif kind == "mission":
            self._mission = item[1]
            ch.log(tp.MISSION, 0, tp.mission_geojson(item[1]))
        elif kind == "status":
            _, t, (mode, armed, seq) = item
            text = f"{mode.value}, {'armed' if armed else 'disarmed'}, mission item {seq}"
            ch.log(tp.LOG, t, tp.log(t, text, name="autopilot"))
        elif kind == "text":
            _, t, text, severity = item
            ch.log(tp.LOG, t, tp.log(t, text, name="vehicle", level=_level(severity)))

    def _state(self, state: VehicleState, nav: NavEstimate | None) -> None:
        ch = self.channels
        t = state.sim_time_ns
        enu, q = _enu_q(state)
        geo = GeoPoint(lat_deg=state.lat_deg, lon_deg=state.lon_deg, alt_amsl_m=state.alt_amsl_m)
        ch.log(f"{tp.TRUTH}/fix", t, tp.location_fix(t, geo, tp.colour_of(tp.TRUTH)))
        ch.log(f"{tp.TRUTH}/pose", t, tp.pose(t, enu, q))
        ch.log(tp.TF_TOPIC, t, tp.transforms(t, enu, q, self.camera))
        if nav is None:
            return
        t_nav = nav.sim_time_ns
        nav_geo = GeoPoint(lat_deg=nav.lat_deg, lon_deg=nav.lon_deg, alt_amsl_m=nav.alt_amsl_m)
        cov = tp.diagonal_cov(nav.std_h_m, nav.std_v_m)
        fix = tp.location_fix(
            t_nav, nav_geo, tp.colour_of(tp.NAV), cov_enu_m2=cov, approximated=True
        )
        nav_enu = ned2enu(nav.pos_ned_m)
        ch.log(f"{tp.NAV}/fix", t_nav, fix)
        ch.log(
            f"{tp.NAV}/pose",
            t_nav,
            tp.pose(t_nav, nav_enu, q_frd_ned_to_flu_enu(nav.q_body_to_ned_wxyz)),
        )
        ch.log(tp.ERRORS, t_nav, tp.errors(t_nav, tp.NAV, enu, nav_enu))

    def _gnss(self, fix: GpsFix) -> None:
        if fix.fix_type < 2:
            return  # silent while GNSS is denied or lost
        geo = GeoPoint(lat_deg=fix.lat_deg, lon_deg=fix.lon_deg, alt_amsl_m=fix.alt_amsl_m)
        cov = tp.diagonal_cov(fix.eph_m, fix.epv_m)
        msg = tp.location_fix(
            fix.sim_time_ns, geo, tp.colour_of(tp.GNSS), cov_enu_m2=cov, approximated=True
        )
        self.channels.log(f"{tp.GNSS}/fix", fix.sim_time_ns, msg)

    def _estimate(self, name: str, t: int, est: Estimate) -> None:
        if self.home is None:
            return
        index = self._estimators.setdefault(name, len(self._estimators))
        source = tp.estimate_source(name)
        h = self.home
        if est.enu_m is not None:
            enu = est.enu_m
        elif est.geo is not None:
            enu = ned2enu(
                geodetic2ned(
                    est.geo.lat_deg,
                    est.geo.lon_deg,
                    est.geo.alt_amsl_m,
                    h.lat_deg,
                    h.lon_deg,
                    h.alt_amsl_m,
                )
            )
        else:
            return
        geo = est.geo
        if geo is None:
            lat, lon, alt = ned2geodetic(
                enu[1], enu[0], -enu[2], h.lat_deg, h.lon_deg, h.alt_amsl_m
            )
            geo = GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
        q = None
        if est.q_body_to_ned_wxyz is not None:
            q = q_frd_ned_to_flu_enu(est.q_body_to_ned_wxyz)
        colour = tp.colour_of(source, index)
        self.channels.log(
            f"{source}/fix", t, tp.location_fix(t, geo, colour, cov_enu_m2=est.cov_enu_m2)
        )
        self.channels.log(f"{source}/pose", t, tp.pose(t, enu, q))
        self._take_truth()
        truth = self._truth.get(t)
        if truth is not None:
            self.channels.log(tp.ERRORS, t, tp.errors(t, source, truth, enu))


def _enu_q(state: VehicleState) -> tuple[Vec3, Quat]:
    return ned2enu(state.pos_ned_m), q_frd_ned_to_flu_enu(state.q_body_to_ned_wxyz)


def _level(severity: int) -> LogLevel:
    """MAVLink severity (0 emergency .. 7 debug) as a Foxglove log level."""
    if severity <= 2:
        return LogLevel.Fatal
    if severity == 3:
        return LogLevel.Error
    if severity == 4:
        return LogLevel.Warning
    if severity <= 6:
        return LogLevel.Info
    return LogLevel.Debug
