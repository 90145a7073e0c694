"""The MAVLink vehicle: links, mission protocol, commands, parameters and telemetry streams.

Threads: the simulation thread calls :class:`TelemetrySink` (a Sink) at every physics step and
runs the jobs this module posts (autopilot commands, parameter sets); one I/O thread owns the
sockets, the mission protocol and all encoding. They talk through queues only: the simulation
never waits for a socket. Stream rates are kept in simulated time and capped in wall time;
the heartbeat is sent every wall-clock second whatever the simulation speed.
"""

from __future__ import annotations

import contextlib
import functools
import math
import queue
import selectors
import socket
import struct
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from air_sitl.errors import AirSitlError
from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import (
    Encoder,
    Message,
    ParseCounters,
    Parser,
    Signing,
    from_mission_message,
    mav,
    to_mission_message,
)
from air_sitl.mavlink.fence import Zone, breach, zones_of
from air_sitl.mavlink.links import Channel, Link, LinkSpec, open_link
from air_sitl.mavlink.messages import Peer
from air_sitl.mavlink.mission_protocol import Failed, MissionProtocol, Replaced, Send
from air_sitl.mission.items import Mission, MissionItem, MissionResult, MissionType
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, FlightMode, GeoPoint, GpsFix, SimSample

NS_PER_S = 1_000_000_000
HEARTBEAT_PERIOD_S = 1.0  # wall clock
WALL_CAP_HZ = 50.0  # no stream goes faster than max(this, its own rate) in wall time
EVENT_PERIOD_NS = 50_000_000  # autopilot events polled every 50 ms of simulated time
FENCE_PERIOD_NS = 200_000_000
SEVERITY_CRITICAL, SEVERITY_WARNING, SEVERITY_INFO = 2, 4, 6


class AutopilotLike(Protocol):
    """The autopilot commands the endpoint uses (run on the simulation thread only)."""

    def arm(self) -> Any: ...
    def disarm(self) -> Any: ...
    def set_mode(self, mode: FlightMode) -> Any: ...
    def start_mission(self) -> Any: ...
    def set_mission(self, mission: Mission) -> Any: ...
    def set_current(self, seq: int) -> Any: ...
    def takeoff(self, alt_m: float) -> Any: ...
    def return_to_launch(self) -> Any: ...
    def reposition(self, lat_deg: float, lon_deg: float, alt_m: float) -> Any: ...
    def change_speed(self, speed_m_s: float) -> Any: ...
    def start_capture(self) -> Any: ...
    def stop_capture(self) -> Any: ...
    def pop_events(self) -> list[str]: ...


class ParamsLike(Protocol):
    """The parameter store served over the parameter protocol."""

    def names(self) -> tuple[str, ...]: ...
    def get(self, name: str) -> float: ...
    def set(self, name: str, value: float) -> float: ...
    def spec(self, name: str) -> Any: ...


Job = Callable[[AutopilotLike], None]
PostFn = Callable[[Job], None]


def _whole(value: float) -> int:
    """A command parameter as an integer; -1 for NaN or infinity."""
    return round(value) if math.isfinite(value) else -1


def _outcome(value: Any) -> tuple[bool, str]:
    """Normalise what an autopilot command returned: None/True, False, or (ok, reason)."""
    if isinstance(value, tuple) and len(value) == 2:
        return bool(value[0]), str(value[1] or "")
    if value is None:
        return True, ""
    return bool(value), ""


@dataclass(frozen=True, slots=True, kw_only=True)
class EndpointOptions:
    """Identity and behaviour of the endpoint."""

    system_id: int = 1
    component_id: int = mav.MAV_COMP_ID_AUTOPILOT1
    signing_key: bytes | None = None
    wall_cap_hz: float = WALL_CAP_HZ


class TelemetrySink:
    """The endpoint's Sink: sees every SimSample on the simulation thread, never blocks."""

    def __init__(self, endpoint: VehicleEndpoint) -> None:
        self._ep = endpoint
        self._next_due: dict[int, int] = {}
        self._last_wall: dict[int, float] = {}
        self._next_any_due_ns = 0
        self._next_event_ns = 0
        self._next_fence_ns = 0
        self._last_key: tuple[FlightMode, bool] | None = None
        self._last_seq = -2
        self._last_completed = False
        self._last_reached = -1
        self._fence_latched = False
        self.zones: tuple[Zone, ...] = ()
        self.last_fix: GpsFix | None = None

    def on_sample(self, sample: SimSample) -> None:
        """Queue what is due: events at once, streams by simulated time with a wall cap."""
        ep = self._ep
        ep.latest = sample
        if sample.gps is not None:
            self.last_fix = sample.gps
        ap = sample.autopilot
        t = sample.state.sim_time_ns
        if ap.reached_seq >= 0:
            seq = self._last_reached = ap.reached_seq
            ep.to_io(lambda: ep.broadcast(mav.MAVLink_mission_item_reached_message(seq)))
        key = (ap.mode, ap.armed)
        if key != self._last_key:
            self._last_key = key
            ep.to_io(ep.send_heartbeat)
        if ap.current_seq != self._last_seq or ap.mission_completed != self._last_completed:
            if ap.mission_completed and not self._last_completed:
                # MAVSDK counts a mission done when the last item is reached, DO items included.
                last = len(ep.protocol.items(MissionType.MISSION)) - 1
                if last >= 0 and self._last_reached != last:
                    self._last_reached = last
                    ep.to_io(lambda: ep.broadcast(mav.MAVLink_mission_item_reached_message(last)))
            self._last_seq, self._last_completed = ap.current_seq, ap.mission_completed
            ep.to_io(lambda: ep.send_stream(mav.MAVLINK_MSG_ID_MISSION_CURRENT, sample, None))
        if t >= self._next_event_ns:
            self._next_event_ns = t + EVENT_PERIOD_NS
            self._poll_events()
        if self.zones and t >= self._next_fence_ns:
            self._next_fence_ns = t + FENCE_PERIOD_NS
            self._check_fence(sample)
        if t >= self._next_any_due_ns:
            self._streams(sample, t)

    def _poll_events(self) -> None:
        ap = self._ep.autopilot
        if ap is None:
            return
        for text in ap.pop_events():
            self._ep.text(SEVERITY_INFO, text)

    def _streams(self, sample: SimSample, t: int) -> None:
        intervals = self._ep.intervals_ns
        now = time.monotonic()
        due: list[int] = []
        next_any = t + NS_PER_S
        for msg_id, interval in intervals.items():
            if interval <= 0:
                continue
            when = self._next_due.get(msg_id, 0)
            if t >= when:
                rate_hz = NS_PER_S / interval
                if now - self._last_wall.get(msg_id, -1e9) >= 1.0 / max(
                    self._ep.options.wall_cap_hz, rate_hz
                ):
                    due.append(msg_id)
                    self._last_wall[msg_id] = now
                when = when + interval if t - when < interval else t + interval
                self._next_due[msg_id] = when
            next_any = min(next_any, when)
        self._next_any_due_ns = next_any
        if due:
            fix = self.last_fix
            ep = self._ep
            ep.to_io(lambda: ep.send_streams(due, sample, fix))

    def _check_fence(self, sample: SimSample) -> None:
        st, ap = sample.state, sample.autopilot
        why = breach(self.zones, st.lat_deg, st.lon_deg)
        if why is None:
            self._fence_latched = False
            return
        if self._fence_latched or not ap.armed or st.on_ground:
            return
        self._fence_latched = True
        if ap.mode in (FlightMode.RTL, FlightMode.LAND):
            return
        autopilot = self._ep.autopilot
        if autopilot is not None:
            autopilot.return_to_launch()
        self._ep.text(SEVERITY_CRITICAL, f"Geofence breached ({why}): RTL")

    def on_frame(self, frame: CameraFrame) -> None:
        """Frames are not sent over MAVLink."""

    def close(self, result: FlightResult) -> None:
        """The flight ended: say so to the clients."""
        self._ep.text(SEVERITY_INFO, "Simulation stopped")


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
        self.protocol = MissionProtocol(mission=m.items, fence=m.fence, rally=m.rally)
        self.counters = ParseCounters()
        self.sink = TelemetrySink(self)
        self.sink.zones = zones_of(m.fence)
        self.latest: SimSample | None = None
        self.autopilot: AutopilotLike | None = None
        self.params: ParamsLike | None = None
        self.intervals_ns: dict[int, int] = {
            k: round(NS_PER_S / v) for k, v in tm.DEFAULT_RATES_HZ.items()
        }
        self._routes: dict[Peer, Channel] = {}
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
        self.to_io(lambda: self.broadcast(tm.statustext(severity, text)))

    def _on_sim(self, job: Job) -> None:
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
                self._guard(functools.partial(link.on_ready, sel, key, mask))
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
            self._guard(fn)

    def _guard(self, fn: Callable[[], None]) -> None:
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

    def broadcast(self, msg: Message) -> None:
        """Send one message on every link to every peer."""
        for link in self._links:
            link.send(link.encoder.encode(msg))  # type: ignore[attr-defined]

    def reply(self, ch: Channel, msg: Message) -> None:
        """Send one message to one peer."""
        ch.link.send(ch.link.encoder.encode(msg), ch)  # type: ignore[attr-defined]

    def send_streams(self, ids: Sequence[int], sample: SimSample, fix: GpsFix | None) -> None:
        """Send the due telemetry messages built from ``sample``."""
        for msg_id in ids:
            self.send_stream(msg_id, sample, fix)

    def _build(self, msg_id: int, sample: SimSample | None, fix: GpsFix | None) -> Message | None:
        if msg_id == mav.MAVLINK_MSG_ID_HEARTBEAT:
            mode, armed = (
                (sample.autopilot.mode, sample.autopilot.armed)
                if sample
                else (FlightMode.IDLE, False)
            )
            return tm.heartbeat(mode, armed)
        if msg_id == mav.MAVLINK_MSG_ID_SYS_STATUS:
            return tm.sys_status(tm.Health(errors_comm=self.counters.dropped))
        if msg_id == mav.MAVLINK_MSG_ID_HOME_POSITION:
            return tm.home_position(self.home, sample.state.sim_time_ns if sample else 0)
        if msg_id == mav.MAVLINK_MSG_ID_MISSION_CURRENT:
            return tm.mission_current(sample, len(self.protocol.items(MissionType.MISSION)))
        if msg_id == mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            return tm.autopilot_version()
        if msg_id == mav.MAVLINK_MSG_ID_CAMERA_INFORMATION:
            return tm.camera_information(sample.state.sim_time_ns if sample else 0)
        if sample is None:
            return None
        s = sample
        builders: dict[int, Callable[[], Message]] = {
            mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: lambda: tm.global_position_int(s, self.home),
            mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED: lambda: tm.local_position_ned(sample),
            mav.MAVLINK_MSG_ID_ATTITUDE: lambda: tm.attitude(sample),
            mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: lambda: tm.attitude_quaternion(sample),
            mav.MAVLINK_MSG_ID_GPS_RAW_INT: lambda: tm.gps_raw_int(sample, fix),
            mav.MAVLINK_MSG_ID_VFR_HUD: lambda: tm.vfr_hud(sample),
            mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: lambda: tm.extended_sys_state(sample),
        }  # fmt: skip
        build = builders.get(msg_id)
        return build() if build is not None else None

    def send_stream(self, msg_id: int, sample: SimSample | None, fix: GpsFix | None) -> None:
        """Send one telemetry message to every client."""
        msg = self._build(msg_id, sample, fix)
        if msg is not None:
            self.broadcast(msg)

    # --- receiving ------------------------------------------------------------------------

    def _receive(self, ch: Channel, data: bytes, datagram: bool) -> None:
        parser: Parser = ch.parser  # type: ignore[assignment]
        for msg in parser.feed(data, datagram=datagram):
            self._guard(functools.partial(self._dispatch, ch, msg))

    def _for_us(self, msg: Message) -> bool:
        ts = getattr(msg, "target_system", 0)
        tc = getattr(msg, "target_component", 0)
        # 190 (MAV_COMP_ID_MISSIONPLANNER): older ground stations address missions to it.
        return ts in (0, self.options.system_id) and tc in (0, self.options.component_id, 190)

    def _dispatch(self, ch: Channel, msg: Message) -> None:
        src = Peer(msg.get_srcSystem(), msg.get_srcComponent())
        if (src.system_id, src.component_id) == (
            self.options.system_id,
            self.options.component_id,
        ):
            return  # our own frames echoed back
        self._routes[src] = ch
        if not self._for_us(msg):
            return
        mission_msg = to_mission_message(msg)
        if mission_msg is not None:
            for out in self.protocol.handle(src, mission_msg, time.monotonic_ns()):
                self._protocol_output(out)
            return
        name = msg.get_type()
        handler = self._handlers.get(name)
        if handler is not None:
            handler(self, ch, msg)

    def _protocol_output(self, out: Send | Replaced | Failed) -> None:
        if isinstance(out, Send):
            ch = self._routes.get(out.peer)
            if ch is not None:
                msg = from_mission_message(out.message, out.peer.system_id, out.peer.component_id)
                self.reply(ch, msg)
        elif isinstance(out, Replaced):
            self._on_replaced(out.mission_type, out.items)
        elif out.result != MissionResult.OPERATION_CANCELLED or "timed out" in out.reason:
            self.broadcast(tm.statustext(SEVERITY_WARNING, f"Upload refused: {out.reason}"))

    def _on_replaced(self, mission_type: MissionType, items: tuple[MissionItem, ...]) -> None:
        if mission_type is MissionType.FENCE:
            zones = zones_of(items)
            sink = self.sink

            def set_fence(_ap: AutopilotLike) -> None:
                sink.zones = zones

            self._on_sim(set_fence)
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
            ap.set_mission(mission)

        self._on_sim(load)

    # --- commands -------------------------------------------------------------------------

    def _ack(self, ch: Channel, msg: Message, result: int, text: str = "") -> None:
        if text:
            sev = SEVERITY_INFO if result == mav.MAV_RESULT_ACCEPTED else SEVERITY_CRITICAL
            self.broadcast(tm.statustext(sev, text))
        ack = mav.MAVLink_command_ack_message(
            msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        self.reply(ch, ack)

    def _command_on_sim(
        self, ch: Channel, msg: Message, fn: Callable[[AutopilotLike], tuple[int, str]]
    ) -> None:
        """Run an autopilot command on the simulation thread, then ACK it from here."""
        if self.autopilot is None:
            self._ack(ch, msg, mav.MAV_RESULT_TEMPORARILY_REJECTED)
            return

        def job(ap: AutopilotLike) -> None:
            try:
                result, text = fn(ap)
            except AirSitlError as err:
                result, text = mav.MAV_RESULT_DENIED, str(err)
            except Exception as err:  # a bug in the autopilot: keep the vehicle serving
                traceback.print_exc(file=sys.stderr)
                result, text = mav.MAV_RESULT_FAILED, f"{type(err).__name__}: {err}"
            self.to_io(lambda: self._ack(ch, msg, result, text))

        self._post(job)

    def _on_command(self, ch: Channel, msg: Message) -> None:
        """Every COMMAND_LONG/INT gets a COMMAND_ACK, even when handling it fails."""
        try:
            self._command(ch, msg)
        except Exception as err:
            traceback.print_exc(file=sys.stderr)
            self._ack(ch, msg, mav.MAV_RESULT_FAILED, f"{type(err).__name__}: {err}")

    def _command(self, ch: Channel, msg: Message) -> None:
        cmd = msg.command
        p1, p2, p3, _p4 = msg.param1, msg.param2, msg.param3, msg.param4
        if msg.get_type() == "COMMAND_INT":
            scale = 1e-7 if msg.frame in (0, 3, 5, 6, 10, 11) else 1.0
            p5, p6, p7 = msg.x * scale, msg.y * scale, msg.z
            relative_alt = msg.frame in (3, 6)
        else:
            p5, p6, p7 = msg.param5, msg.param6, msg.param7
            relative_alt = False
        home_alt = self.home.alt_amsl_m
        accepted = mav.MAV_RESULT_ACCEPTED

        def simple(call: Callable[[AutopilotLike], Any], failure: str = "") -> None:
            def fn(ap: AutopilotLike) -> tuple[int, str]:
                ok, reason = _outcome(call(ap))
                if ok:
                    return accepted, ""
                return mav.MAV_RESULT_DENIED, (failure + reason) if reason else failure.rstrip(": ")

            self._command_on_sim(ch, msg, fn)

        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 >= 0.5:
                simple(lambda ap: ap.arm(), "Preflight Fail: ")
            else:
                simple(lambda ap: ap.disarm(), "Disarm denied: ")
        elif cmd == mav.MAV_CMD_DO_SET_MODE:
            mode = tm.PX4_TO_MODE.get((_whole(p2), _whole(p3)))
            if not (_whole(p1) & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) or mode is None:
                self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
                return
            simple(lambda ap: ap.set_mode(mode), f"Mode {mode.name} denied: ")
        elif cmd == mav.MAV_CMD_MISSION_START:
            simple(lambda ap: ap.start_mission(), "Mission start denied: ")
        elif cmd == mav.MAV_CMD_NAV_TAKEOFF:
            alt = (p7 if relative_alt else p7 - home_alt) if math.isfinite(p7) else math.nan
            simple(lambda ap: ap.takeoff(alt), "Takeoff denied: ")
        elif cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            simple(lambda ap: ap.return_to_launch(), "RTL denied: ")
        elif cmd == mav.MAV_CMD_DO_SET_MISSION_CURRENT:
            seq = _whole(p1)
            if not 0 <= seq < len(self.protocol.items(MissionType.MISSION)):
                self._ack(ch, msg, mav.MAV_RESULT_DENIED, f"No mission item {seq}")
                return
            simple(lambda ap: ap.set_current(seq))
        elif cmd == mav.MAV_CMD_DO_REPOSITION:
            alt = p7 + home_alt if relative_alt and math.isfinite(p7) else p7
            here = self.latest
            if here is not None and not (math.isfinite(p5) and math.isfinite(p6)):
                p5, p6 = here.state.lat_deg, here.state.lon_deg  # NaN: loiter where we are
            simple(lambda ap: ap.reposition(p5, p6, alt), "Reposition denied: ")
        elif cmd == mav.MAV_CMD_DO_CHANGE_SPEED:
            if not (math.isfinite(p2) and p2 > 0):
                self._ack(ch, msg, mav.MAV_RESULT_DENIED, f"Bad speed {p2}")
                return
            simple(lambda ap: ap.change_speed(p2), "Speed change denied: ")
        elif cmd == mav.MAV_CMD_IMAGE_START_CAPTURE:
            simple(lambda ap: ap.start_capture())
        elif cmd == mav.MAV_CMD_IMAGE_STOP_CAPTURE:
            simple(lambda ap: ap.stop_capture())
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            self._request_message(ch, msg, _whole(p1))
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            self._set_interval(ch, msg, _whole(p1), p2)
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self._request_message(ch, msg, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        elif cmd == mav.MAV_CMD_GET_HOME_POSITION:
            self._request_message(ch, msg, mav.MAVLINK_MSG_ID_HOME_POSITION)
        elif cmd == mav.MAV_CMD_REQUEST_CAMERA_INFORMATION:
            self._request_message(ch, msg, mav.MAVLINK_MSG_ID_CAMERA_INFORMATION)
        else:
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)

    def _request_message(self, ch: Channel, msg: Message, msg_id: int) -> None:
        reply = self._build(msg_id, self.latest, self.sink.last_fix)
        if reply is None:
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
            return
        self._ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
        self.reply(ch, reply)

    def _set_interval(self, ch: Channel, msg: Message, msg_id: int, interval_us: float) -> None:
        if msg_id not in tm.DEFAULT_RATES_HZ or not math.isfinite(interval_us):
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
            return
        intervals = dict(self.intervals_ns)
        if interval_us == 0:
            intervals[msg_id] = round(NS_PER_S / tm.DEFAULT_RATES_HZ[msg_id])
        elif interval_us < 0:
            intervals[msg_id] = 0
        else:
            intervals[msg_id] = max(round(interval_us * 1000), 1_000_000)  # at most 1 kHz
        self.intervals_ns = intervals  # one reference swap: the sink sees old or new
        self._ack(ch, msg, mav.MAV_RESULT_ACCEPTED)

    # --- other messages -------------------------------------------------------------------

    def _on_set_mode(self, ch: Channel, msg: Message) -> None:
        main, sub = (msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF
        mode = tm.PX4_TO_MODE.get((main, sub))
        if mode is not None:
            self._on_sim(lambda ap: ap.set_mode(mode))

    def _on_mission_set_current(self, ch: Channel, msg: Message) -> None:
        seq = msg.seq
        if not 0 <= seq < len(self.protocol.items(MissionType.MISSION)):
            self.reply(
                ch, tm.mission_current(self.latest, len(self.protocol.items(MissionType.MISSION)))
            )
            return

        def job(ap: AutopilotLike) -> None:
            ap.set_current(seq)

        self._on_sim(job)

    def _on_timesync(self, ch: Channel, msg: Message) -> None:
        if msg.tc1 == 0:
            self.reply(ch, mav.MAVLink_timesync_message(time.monotonic_ns(), msg.ts1))

    # --- parameters -----------------------------------------------------------------------

    def _param_value(self, name: str) -> Message | None:
        params = self.params
        if params is None:
            return None
        names = params.names()
        value = params.get(name)
        if getattr(params.spec(name), "is_int", False):
            packed = struct.unpack("<f", struct.pack("<i", round(value)))[0]
            return mav.MAVLink_param_value_message(
                name.encode("ascii"),
                packed,
                mav.MAV_PARAM_TYPE_INT32,
                len(names),
                names.index(name),
            )
        return mav.MAVLink_param_value_message(
            name.encode("ascii"), value, mav.MAV_PARAM_TYPE_REAL32, len(names), names.index(name)
        )

    @staticmethod
    def _param_name(raw: Any) -> str:
        if isinstance(raw, bytes):
            raw = raw.decode("ascii", errors="replace")
        return str(raw).rstrip("\x00")

    def _on_param_request_list(self, ch: Channel, msg: Message) -> None:
        if self.params is None:
            return
        for name in self.params.names():
            value = self._param_value(name)
            if value is not None:
                self.reply(ch, value)

    def _on_param_request_read(self, ch: Channel, msg: Message) -> None:
        if self.params is None:
            return
        names = self.params.names()
        if msg.param_index >= 0:
            if msg.param_index >= len(names):
                return
            name = names[msg.param_index]
        else:
            name = self._param_name(msg.param_id)
            if name not in names:
                return
        value = self._param_value(name)
        if value is not None:
            self.reply(ch, value)

    def _on_param_set(self, ch: Channel, msg: Message) -> None:
        params = self.params
        if params is None:
            return
        name = self._param_name(msg.param_id)
        if name not in params.names():
            self.reply(ch, tm.statustext(SEVERITY_WARNING, f"Unknown parameter {name}"))
            return
        value = float(msg.param_value)
        if msg.param_type in (mav.MAV_PARAM_TYPE_INT32, mav.MAV_PARAM_TYPE_UINT32):
            value = float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])

        def job(_ap: AutopilotLike) -> None:
            try:
                params.set(name, value)
                problem = ""
            except AirSitlError as err:
                problem = str(err)

            def answer() -> None:
                if problem:
                    self.broadcast(tm.statustext(SEVERITY_WARNING, problem))
                reply = self._param_value(name)
                if reply is not None:
                    self.broadcast(reply)

            self.to_io(answer)

        self._on_sim(job)

    _handlers: ClassVar[dict[str, Callable[[VehicleEndpoint, Channel, Message], None]]] = {
        "COMMAND_LONG": _on_command,
        "COMMAND_INT": _on_command,
        "SET_MODE": _on_set_mode,
        "MISSION_SET_CURRENT": _on_mission_set_current,
        "TIMESYNC": _on_timesync,
        "PARAM_REQUEST_LIST": _on_param_request_list,
        "PARAM_REQUEST_READ": _on_param_request_read,
        "PARAM_SET": _on_param_set,
    }
