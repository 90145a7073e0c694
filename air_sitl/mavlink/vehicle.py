"""The MAVLink vehicle: links, the I/O thread, message dispatch and the mission protocol.

Threads: the simulation thread calls :class:`TelemetrySink` (a Sink) at every physics step and
runs the jobs this module posts (autopilot commands, parameter sets); one I/O thread owns the
sockets, the mission protocol and all encoding. They talk through queues only: the simulation
never waits for a socket. Stream rates are per link, in simulated time, capped in wall time
(:mod:`streams`); the heartbeat is sent every wall-clock second whatever the simulation speed.

Incoming messages are dispatched by type name through :attr:`VehicleEndpoint.handlers`; a new
part registers its messages with :meth:`VehicleEndpoint.register` (see :mod:`commands`,
:mod:`param_protocol`) and its telemetry with ``endpoint.streams.add`` (see :mod:`streams`).
"""

from __future__ import annotations

import contextlib
import functools
import queue
import selectors
import socket
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence

from air_sitl.errors import AirSitlError
from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.camera import COMPONENT_ID as CAMERA_COMPONENT_ID
from air_sitl.mavlink.camera import CameraComponent
from air_sitl.mavlink.codec import (
    Encoder,
    Message,
    ParseCounters,
    Parser,
    Signing,
    from_mission_message,
    to_mission_message,
)
from air_sitl.mavlink.commands import Commands
from air_sitl.mavlink.fence import zones_of
from air_sitl.mavlink.ftp import Ftp
from air_sitl.mavlink.interfaces import (
    SEVERITY_CRITICAL,
    SEVERITY_WARNING,
    WALL_CAP_HZ,
    AutopilotLike,
    EndpointOptions,
    Handler,
    Job,
    ParamsLike,
    PostFn,
)
from air_sitl.mavlink.links import Channel, Link, LinkSpec, open_link
from air_sitl.mavlink.messages import Peer
from air_sitl.mavlink.mission_protocol import Failed, MissionProtocol, Replaced, Send
from air_sitl.mavlink.param_protocol import ParamProtocol
from air_sitl.mavlink.streams import Streams, TelemetrySink
from air_sitl.mission.items import Mission, MissionItem, MissionResult, MissionType
from air_sitl.state import FlightMode, GeoPoint, SimSample

__all__ = [
    "WALL_CAP_HZ",
    "AutopilotLike",
    "EndpointOptions",
    "Job",
    "ParamsLike",
    "PostFn",
    "TelemetrySink",
    "VehicleEndpoint",
]

HEARTBEAT_PERIOD_S = 1.0  # wall clock
MAX_ROUTES = 1024  # peers remembered for replies; forgotten ones are the links' dropped peers


class VehicleEndpoint:
    """One simulated PX4 vehicle on a set of MAVLink links."""

    def __init__(
        self,
        links: Sequence[LinkSpec],
        *,
        home: GeoPoint,
        mission: Mission | None = None,
        post: PostFn,
        options: EndpointOptions | None = None,
    ) -> None:
        self.options = options or EndpointOptions()
        self.home = home
        self._specs = tuple(links)
        self._post = post
        self._signing = (
            Signing(self.options.signing_key) if self.options.signing_key is not None else None
        )
        m = mission or Mission(items=())
        self._mission_meta = m
        self.protocol = MissionProtocol(
            mission=m.items, fence=m.fence, rally=m.rally, terrain=self.options.terrain
        )
        self.counters = ParseCounters()
        self.streams = Streams(self)
        self.sink = TelemetrySink(self, self.streams)
        self.sink.zones = zones_of(m.fence)
        self.latest: SimSample | None = None
        self.images_captured = 0  # capture-window frames so far (CAMERA_CAPTURE_STATUS)
        self.autopilot: AutopilotLike | None = None
        self.params: ParamsLike | None = None
        self._routes: dict[int, Channel] = {}  # Peer.route -> the channel it came from
        self._links: list[Link] = []
        self._queue: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._wake_pending = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._next_heartbeat = 0.0
        self.heartbeats_sent = 0
        self.io_errors = 0
        self._text_id = 0
        # Called with (severity, text) of every STATUSTEXT broadcast (I/O thread): a live view.
        self.text_listeners: list[Callable[[int, str], None]] = []
        # Called with every mission a client uploads (I/O thread): a live view's plan.
        self.mission_listeners: list[Callable[[Mission], None]] = []
        self.commands = Commands(self)
        self.param_protocol = ParamProtocol(self)
        self.handlers: dict[str, Handler] = {}
        cam = self.options.camera
        self.camera = CameraComponent(self, cam, self.options.video) if cam is not None else None
        for part in (self.commands, self.param_protocol, Ftp(self)):
            for name, handler in part.handlers().items():
                self.register(name, handler)

    def register(self, message_type: str, handler: Handler) -> None:
        """Call ``handler(channel, msg)`` on the I/O thread for each ``message_type`` received
        (a pymavlink type name such as ``"ODOMETRY"``) addressed to this vehicle."""
        self.handlers[message_type] = handler

    # --- life cycle -----------------------------------------------------------------------

    def attach(self, autopilot: AutopilotLike, params: ParamsLike | None) -> None:
        """Connect to the flight's autopilot and parameter store (before :meth:`start`)."""
        self.autopilot = autopilot
        self.params = params

    def open(self) -> list[tuple[str, int]]:
        """Open every link (MavlinkError when a socket cannot be opened); their addresses."""
        for spec in self._specs:
            encoder = Encoder(self.options.system_id, self.options.component_id, self._signing)
            self._links.append(open_link(spec, encoder, self._receive, self._new_parser))
        self.streams.links_opened(self._links)
        if self.camera is not None:
            self.camera.open(tuple(self._links), self._signing)
        return [link.local_address for link in self._links]

    def start(self) -> None:
        """Open the links if needed and start the I/O thread."""
        if not self._links:
            self.open()
        self._thread = threading.Thread(target=self._run, name="mavlink-io", daemon=True)
        self._thread.start()

    def close(self) -> None:
        """Stop the I/O thread and close every socket (idempotent)."""
        self._stop.set()
        self._wake()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None
        for link in self._links:
            link.close()
        self._links = []
        self._wake_r.close()
        self._wake_w.close()

    @property
    def io_running(self) -> bool:
        """The I/O thread runs (started and not stopping)."""
        thread = self._thread
        return thread is not None and thread.is_alive() and not self._stop.is_set()

    @property
    def links(self) -> tuple[Link, ...]:
        """The open links."""
        return tuple(self._links)

    def _new_parser(self) -> Parser:
        return Parser(self.counters, self._signing)

    # --- cross-thread plumbing ------------------------------------------------------------

    def to_io(self, fn: Callable[[], None]) -> None:
        """Run ``fn`` on the I/O thread soon (callable from any thread, never blocks)."""
        self._queue.put(fn)
        self._wake()

    def _wake(self) -> None:
        if self._wake_pending:
            return
        self._wake_pending = True
        with contextlib.suppress(OSError):
            self._wake_w.send(b"x")

    def text(self, severity: int, text: str) -> None:
        """Queue a STATUSTEXT to every client."""
        self.to_io(lambda: self.broadcast_text(severity, text))

    def statustext(self, severity: int, text: str) -> list[Message]:
        """The STATUSTEXT message(s) of ``text``, chunked with a fresh id when it is long."""
        self._text_id = self._text_id % 0xFFFF + 1
        return tm.statustext(severity, text, self._text_id)

    def broadcast_text(self, severity: int, text: str) -> None:
        """STATUSTEXT to every client now (I/O thread)."""
        for listener in self.text_listeners:
            listener(severity, text)
        for msg in self.statustext(severity, text):
            self.broadcast(msg)

    def reply_text(self, ch: Channel, severity: int, text: str) -> None:
        """STATUSTEXT to one peer now (I/O thread)."""
        for msg in self.statustext(severity, text):
            self.reply(ch, msg)

    def post(self, job: Job) -> None:
        """Run ``job`` on the simulation thread as it is (it handles its own errors)."""
        self._post(job)

    def on_sim(self, job: Job) -> None:
        """Run ``job`` on the simulation thread; its errors become STATUSTEXT, never a crash."""
        if self.autopilot is None:
            return

        def safe(ap: AutopilotLike) -> None:
            try:
                job(ap)
            except AirSitlError as err:
                self.text(SEVERITY_WARNING, str(err))
            except Exception as err:
                traceback.print_exc(file=sys.stderr)
                self.text(SEVERITY_CRITICAL, f"{type(err).__name__}: {err}")

        self._post(safe)

    # --- I/O thread -----------------------------------------------------------------------

    def _run(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self._wake_r, selectors.EVENT_READ, None)
        for link in self._links:
            link.register(sel)
        self._next_heartbeat = time.monotonic()
        while not self._stop.is_set():
            timeout = max(0.0, min(self._next_heartbeat - time.monotonic(), 0.05))
            for key, mask in sel.select(timeout):
                if key.data is None:
                    self._wake_pending = False
                    try:
                        while self._wake_r.recv(4096):
                            pass
                    except (BlockingIOError, InterruptedError, OSError):
                        pass
                    continue
                link = key.data if isinstance(key.data, Link) else key.data[0]
                self.guard(functools.partial(link.on_ready, sel, key, mask))
            self._drain()
            now = time.monotonic()
            if now >= self._next_heartbeat:
                self._next_heartbeat = max(self._next_heartbeat + HEARTBEAT_PERIOD_S, now + 0.5)
                self.send_heartbeat()
            for out in self.protocol.tick(time.monotonic_ns()):
                self._protocol_output(out)
        sel.close()

    def _drain(self) -> None:
        for _ in range(10_000):
            try:
                fn = self._queue.get_nowait()
            except queue.Empty:
                return
            self.guard(fn)

    def guard(self, fn: Callable[[], None]) -> None:
        """Run ``fn``; a bug in one handler must not kill the link thread."""
        try:
            fn()
        except Exception:
            self.io_errors += 1
            traceback.print_exc(file=sys.stderr)

    def send_heartbeat(self) -> None:
        """HEARTBEAT to every client, from the latest simulated state."""
        s = self.latest
        mode, armed = (s.autopilot.mode, s.autopilot.armed) if s else (FlightMode.IDLE, False)
        self.broadcast(tm.heartbeat(mode, armed))
        self.heartbeats_sent += 1
        if self.camera is not None:
            self.camera.send_heartbeat()

    def broadcast(self, msg: Message) -> None:
        """Send one message on every link to every peer."""
        for link in self._links:
            link.send(link.encoder.encode(msg))  # type: ignore[attr-defined]

    def reply(self, ch: Channel, msg: Message) -> None:
        """Send one message to one peer."""
        ch.link.send(ch.link.encoder.encode(msg), ch)  # type: ignore[attr-defined]

    # --- receiving ------------------------------------------------------------------------

    def _receive(self, ch: Channel, data: bytes, datagram: bool) -> None:
        parser: Parser = ch.parser  # type: ignore[assignment]
        for msg in parser.feed(data, datagram=datagram):
            self.guard(functools.partial(self._dispatch, ch, msg))

    def _for_us(self, msg: Message) -> bool:
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        # 190 (MAV_COMP_ID_MISSIONPLANNER): older ground stations address missions to it.
        return ts in (0, self.options.system_id) and tc in (0, self.options.component_id, 190)

    def _dispatch(self, ch: Channel, msg: Message) -> None:
        src = Peer(msg.get_srcSystem(), msg.get_srcComponent(), id(ch))
        if (src.system_id, src.component_id) == (
            self.options.system_id,
            self.options.component_id,
        ):
            return  # our own frames echoed back
        if src.route not in self._routes and len(self._routes) >= MAX_ROUTES:
            live = {id(c) for link in self._links for c in link.channels.values()}
            self._routes = {r: c for r, c in self._routes.items() if r in live}
        self._routes[src.route] = ch
        if self.camera is not None and getattr(msg, "target_component", 0) == CAMERA_COMPONENT_ID:
            if getattr(msg, "target_system", 0) in (0, self.options.system_id):
                self.camera.on_message(ch, msg)
            return
        if not self._for_us(msg):
            return
        mission_msg = to_mission_message(msg)
        if mission_msg is not None:
            for out in self.protocol.handle(src, mission_msg, time.monotonic_ns()):
                self._protocol_output(out)
            return
        handler = self.handlers.get(msg.get_type())
        if handler is not None:
            handler(ch, msg)

    # --- mission protocol -----------------------------------------------------------------

    def _protocol_output(self, out: Send | Replaced | Failed) -> None:
        if isinstance(out, Send):
            ch = self._routes.get(out.peer.route)
            if ch is not None:
                msg = from_mission_message(out.message, out.peer.system_id, out.peer.component_id)
                self.reply(ch, msg)
        elif isinstance(out, Replaced):
            if out.mission_type is MissionType.MISSION and not out.changed:
                return  # PX4 ignores a re-upload of the same mission: nothing restarts
            self._on_replaced(out.mission_type, out.items, out.current_seq)
        elif out.result != MissionResult.OPERATION_CANCELLED or "timed out" in out.reason:
            self.broadcast_text(SEVERITY_WARNING, f"Upload refused: {out.reason}")

    def _on_replaced(
        self, mission_type: MissionType, items: tuple[MissionItem, ...], current_seq: int = -1
    ) -> None:
        if mission_type is MissionType.FENCE:
            zones = zones_of(items)
            sink = self.sink

            def set_fence(_ap: AutopilotLike) -> None:
                sink.zones = zones

            self.on_sim(set_fence)
            if self.autopilot is None:
                sink.zones = zones
            return
        if mission_type is not MissionType.MISSION:
            return
        mission = Mission(
            items=items,
            planned_home=self._mission_meta.planned_home or self.home,
            cruise_speed_m_s=self._mission_meta.cruise_speed_m_s,
            fence=self.protocol.items(MissionType.FENCE),
            rally=self.protocol.items(MissionType.RALLY),
            source="mavlink upload",
            name=self._mission_meta.name,
        )

        def load(ap: AutopilotLike) -> None:
            # As PX4: the item flagged current, else the current index kept (-1).
            ap.set_mission(mission, current_seq)

        self.on_sim(load)
        for listener in self.mission_listeners:
            listener(mission)
