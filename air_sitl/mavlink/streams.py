"""Telemetry streams: what is due at each simulated instant, and the message builders.

:class:`TelemetrySink` runs on the simulation thread (it is the endpoint's Sink): it sees every
SimSample, decides which streams are due in simulated time and posts them to the I/O thread.
:class:`Streams` lives on the I/O thread: the stream intervals and the builder of each message,
a table another module extends with :meth:`Streams.add` (a new message and its default rate).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Message, mav
from air_sitl.mavlink.fence import Zone, breach
from air_sitl.mavlink.interfaces import NS_PER_S, SEVERITY_CRITICAL, SEVERITY_INFO
from air_sitl.mission.items import MissionType
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, FlightMode, GpsFix, SimSample

if TYPE_CHECKING:
    from air_sitl.mavlink.vehicle import VehicleEndpoint

EVENT_PERIOD_NS = 50_000_000  # autopilot events polled every 50 ms of simulated time
FENCE_PERIOD_NS = 200_000_000

# Builds one message from the latest sample and GNSS fix; None when it cannot be built yet.
Builder = Callable[[SimSample | None, GpsFix | None], Message | None]


class Streams:
    """Stream intervals and message builders (used on the I/O thread; read by the sink)."""

    def __init__(self, ep: VehicleEndpoint) -> None:
        self._ep = ep
        self.builders: dict[int, Builder] = {}
        self.default_rates_hz: dict[int, float] = {}
        self.intervals_ns: dict[int, int] = {}
        self._add_standard()

    def add(self, msg_id: int, builder: Builder, rate_hz: float = 0.0) -> None:
        """Serve ``msg_id``: on request (MAV_CMD_REQUEST_MESSAGE), and streamed at ``rate_hz``
        (0: only on request or after SET_MESSAGE_INTERVAL)."""
        self.builders[msg_id] = builder
        self.default_rates_hz[msg_id] = rate_hz
        intervals = dict(self.intervals_ns)
        intervals[msg_id] = round(NS_PER_S / rate_hz) if rate_hz > 0 else 0
        self.intervals_ns = intervals  # one reference swap: the sink sees old or new

    def _add_standard(self) -> None:
        ep = self._ep
        rates = tm.DEFAULT_RATES_HZ

        def needs_sample(fn: Callable[[SimSample], Message]) -> Builder:
            return lambda s, _fix: fn(s) if s is not None else None

        def heartbeat(s: SimSample | None, _fix: GpsFix | None) -> Message:
            mode, armed = (s.autopilot.mode, s.autopilot.armed) if s else (FlightMode.IDLE, False)
            return tm.heartbeat(mode, armed)

        def sim_ns(s: SimSample | None) -> int:
            return s.state.sim_time_ns if s is not None else 0

        standard: dict[int, Builder] = {
            mav.MAVLINK_MSG_ID_HEARTBEAT: heartbeat,
            mav.MAVLINK_MSG_ID_SYS_STATUS: lambda s, _f: tm.sys_status(
                tm.Health(errors_comm=ep.counters.dropped)
            ),
            mav.MAVLINK_MSG_ID_HOME_POSITION: lambda s, _f: tm.home_position(ep.home, sim_ns(s)),
            mav.MAVLINK_MSG_ID_MISSION_CURRENT: lambda s, _f: tm.mission_current(
                s, len(ep.protocol.items(MissionType.MISSION))
            ),
            mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION: lambda _s, _f: tm.autopilot_version(),
            mav.MAVLINK_MSG_ID_CAMERA_INFORMATION: lambda s, _f: tm.camera_information(sim_ns(s)),
            mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: needs_sample(
                lambda s: tm.global_position_int(s, ep.home)
            ),
            mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED: needs_sample(tm.local_position_ned),
            mav.MAVLINK_MSG_ID_ATTITUDE: needs_sample(tm.attitude),
            mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: needs_sample(tm.attitude_quaternion),
            mav.MAVLINK_MSG_ID_GPS_RAW_INT: lambda s, f: (
                tm.gps_raw_int(s, f) if s is not None else None
            ),
            mav.MAVLINK_MSG_ID_VFR_HUD: needs_sample(tm.vfr_hud),
            mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: needs_sample(tm.extended_sys_state),
        }
        for msg_id, builder in standard.items():
            self.add(msg_id, builder, rates.get(msg_id, 0.0))

    def build(self, msg_id: int, sample: SimSample | None, fix: GpsFix | None) -> Message | None:
        """The message ``msg_id`` now; None when unknown or not buildable yet."""
        builder = self.builders.get(msg_id)
        return builder(sample, fix) if builder is not None else None

    def set_interval(self, msg_id: int, interval_us: float) -> bool:
        """SET_MESSAGE_INTERVAL semantics (0 default, -1 off); False for an unknown stream."""
        if msg_id not in self.default_rates_hz or not math.isfinite(interval_us):
            return False
        if msg_id == mav.MAVLINK_MSG_ID_HEARTBEAT:
            return False  # the heartbeat is paced in wall time, not a stream
        intervals = dict(self.intervals_ns)
        if interval_us == 0:
            rate = self.default_rates_hz[msg_id]
            intervals[msg_id] = round(NS_PER_S / rate) if rate > 0 else 0
        elif interval_us < 0:
            intervals[msg_id] = 0
        else:
            intervals[msg_id] = max(round(interval_us * 1000), 1_000_000)  # at most 1 kHz
        self.intervals_ns = intervals  # one reference swap: the sink sees old or new
        return True

    def send(self, ids: Sequence[int], sample: SimSample | None, fix: GpsFix | None) -> None:
        """Build and broadcast the messages ``ids`` from ``sample``."""
        for msg_id in ids:
            msg = self.build(msg_id, sample, fix)
            if msg is not None:
                self._ep.broadcast(msg)


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
            ids = [mav.MAVLINK_MSG_ID_MISSION_CURRENT]
            ep.to_io(lambda: ep.streams.send(ids, sample, None))
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
        intervals = self._ep.streams.intervals_ns
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
            ep.to_io(lambda: ep.streams.send(due, sample, fix))

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
