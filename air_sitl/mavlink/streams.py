"""Telemetry streams: what is due at each simulated instant on each link, and the builders.

Rates are in simulated time at every speed (as PX4 in lockstep SITL): 50 Hz is 50 messages per
simulated second. A token bucket per stream and link holds each stream to at most
``max(wall_cap_hz, its rate)`` per wall second, so a fast simulation cannot flood a ground
station; the default cap (200 Hz) never bites up to 50 Hz at --speed 4 or slower.

:class:`TelemetrySink` runs on the simulation thread (it is the endpoint's Sink): it sees every
SimSample, decides which streams are due in simulated time and posts them to the I/O thread.
:class:`Streams` lives on the I/O thread: the stream intervals and the builder of each message,
a table another module extends with :meth:`Streams.add` (a new message and its default rate).
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Callable, Sequence

from air_sitl import battery
from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Message, mav
from air_sitl.mavlink.fence import Zone, breach
from air_sitl.mavlink.interfaces import (
    NS_PER_S,
    SEVERITY_CRITICAL,
    SEVERITY_INFO,
    SEVERITY_WARNING,
    Builder,
    EndpointLike,
)
from air_sitl.mavlink.links import Link
from air_sitl.mission.items import MissionType
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, FlightMode, GpsFix, SimSample

EVENT_PERIOD_NS = 50_000_000  # autopilot events polled every 50 ms of simulated time
FENCE_PERIOD_NS = 200_000_000
WALL_BURST_S = 0.1  # the wall-clock cap lets a stream catch up this much after a stall
MAX_PENDING_JOBS = 64  # telemetry jobs queued for the I/O thread before the simulation waits
BACKPRESSURE_POLL_S = 0.1  # how often a waiting simulation checks that the I/O thread still runs


# REQUEST_DATA_STREAM groups (ArduPilot's, as MAVProxy expects them) of the streams we have.
DATA_STREAM_GROUPS: dict[int, tuple[int, ...]] = {
    mav.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mav.MAVLINK_MSG_ID_SYS_STATUS,
        mav.MAVLINK_MSG_ID_GPS_RAW_INT,
        mav.MAVLINK_MSG_ID_MISSION_CURRENT,
        mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    mav.MAV_DATA_STREAM_POSITION: (
        mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mav.MAV_DATA_STREAM_EXTRA1: (
        mav.MAVLINK_MSG_ID_ATTITUDE,
        mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION,
    ),
    mav.MAV_DATA_STREAM_EXTRA2: (mav.MAVLINK_MSG_ID_VFR_HUD,),
    mav.MAV_DATA_STREAM_EXTRA3: (mav.MAVLINK_MSG_ID_BATTERY_STATUS,),
}
Intervals = dict[int, int]  # message id -> interval in simulated ns (0: off)


class Streams:
    """Stream intervals of each link, and the message builders (I/O thread; the sink reads).

    Like PX4, each link (a MAVLink instance) has its own stream rates: SET_MESSAGE_INTERVAL and
    REQUEST_DATA_STREAM change those of the link they arrive on only.
    """

    def __init__(self, ep: EndpointLike) -> None:
        self._ep = ep
        self.builders: dict[int, Builder] = {}
        self.default_rates_hz: dict[int, float] = {}
        self._defaults: Intervals = {}
        self._overrides: dict[Link, Intervals] = {}
        self.tables: dict[Link, Intervals] = {}  # replaced whole: the sink sees old or new
        self._add_standard()

    def add(self, msg_id: int, builder: Builder, rate_hz: float = 0.0) -> None:
        """Serve ``msg_id``: on request (MAV_CMD_REQUEST_MESSAGE), and streamed at ``rate_hz``
        of simulated time on every link (0: only on request or after SET_MESSAGE_INTERVAL)."""
        self.builders[msg_id] = builder
        self.default_rates_hz[msg_id] = rate_hz
        self._defaults[msg_id] = _interval_ns(rate_hz)
        self._publish()

    def links_opened(self, links: Sequence[Link]) -> None:
        """Give each link its table (default rates)."""
        for link in links:
            self._overrides.setdefault(link, {})
        self._publish()

    def _publish(self) -> None:
        self.tables = {link: {**self._defaults, **own} for link, own in self._overrides.items()}

    def intervals_ns(self, link: Link) -> Intervals:
        """The stream intervals of ``link``."""
        return self.tables.get(link, self._defaults)

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
                tm.Health(errors_comm=ep.counters.dropped), s.battery if s is not None else None
            ),
            mav.MAVLINK_MSG_ID_BATTERY_STATUS: self._battery_status,
            mav.MAVLINK_MSG_ID_HOME_POSITION: lambda s, _f: tm.home_position(ep.home, sim_ns(s)),
            mav.MAVLINK_MSG_ID_MISSION_CURRENT: lambda s, _f: tm.mission_current(
                s, len(ep.protocol.items(MissionType.MISSION))
            ),
            mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION: lambda _s, _f: tm.autopilot_version(),
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

    def _battery_status(self, s: SimSample | None, _fix: GpsFix | None) -> Message | None:
        params = self._ep.params
        if s is None or s.battery is None or params is None:
            return None
        level = battery.warning_level(
            s.battery.remaining,
            params.get("BAT_LOW_THR"),
            params.get("BAT_CRIT_THR"),
            params.get("BAT_EMERGEN_THR"),
        )
        return tm.battery_status(s.battery, round(params.get("BAT1_N_CELLS")), level)

    def build(self, msg_id: int, sample: SimSample | None, fix: GpsFix | None) -> Message | None:
        """The message ``msg_id`` now; None when unknown or not buildable yet."""
        builder = self.builders.get(msg_id)
        return builder(sample, fix) if builder is not None else None

    def _set(self, link: Link, changes: Intervals) -> None:
        own = dict(self._overrides.get(link, {}))
        own.update(changes)
        self._overrides[link] = own
        self._publish()

    def set_interval(self, link: Link, msg_id: int, interval_us: float) -> bool:
        """SET_MESSAGE_INTERVAL on ``link`` (0 default, -1 off); False for an unknown stream."""
        if msg_id not in self.default_rates_hz or not math.isfinite(interval_us):
            return False
        if msg_id == mav.MAVLINK_MSG_ID_HEARTBEAT:
            return False  # the heartbeat is paced in wall time, not a stream
        if interval_us == 0:
            interval = self._defaults[msg_id]
        elif interval_us < 0:
            interval = 0
        else:
            interval = max(round(interval_us * 1000), 1_000_000)  # at most 1 kHz
        self._set(link, {msg_id: interval})
        return True

    def request_data_stream(self, link: Link, stream_id: int, rate_hz: int, start: bool) -> None:
        """REQUEST_DATA_STREAM on ``link`` as ArduPilot: a group's messages at ``rate_hz``,
        stopped by ``start`` 0 or a rate of 0; MAV_DATA_STREAM_ALL sets every group."""
        if stream_id == mav.MAV_DATA_STREAM_ALL:
            ids = [i for group in DATA_STREAM_GROUPS.values() for i in group]
        else:
            ids = list(DATA_STREAM_GROUPS.get(stream_id, ()))
        interval = _interval_ns(float(rate_hz)) if start else 0
        self._set(link, {i: interval for i in ids if i in self.builders})

    def send(self, ids: Sequence[int], sample: SimSample | None, fix: GpsFix | None) -> None:
        """Build and broadcast the messages ``ids`` from ``sample``."""
        for msg_id in ids:
            msg = self.build(msg_id, sample, fix)
            if msg is not None:
                self._ep.broadcast(msg)

    def send_on(
        self, link: Link, ids: Sequence[int], sample: SimSample, fix: GpsFix | None
    ) -> None:
        """Build the messages ``ids`` and send them to every peer of ``link``."""
        for msg_id in ids:
            msg = self.build(msg_id, sample, fix)
            if msg is not None:
                link.send(link.encoder.encode(msg))  # type: ignore[attr-defined]


def _interval_ns(rate_hz: float) -> int:
    return round(NS_PER_S / rate_hz) if rate_hz > 0 and math.isfinite(rate_hz) else 0


class TelemetrySink:
    """The endpoint's Sink: sees every SimSample on the simulation thread, never blocks."""

    def __init__(self, endpoint: EndpointLike, streams: Streams) -> None:
        self._ep = endpoint
        self._message_streams = streams
        self._next_due: dict[tuple[int, int], int] = {}
        self._tokens: dict[tuple[int, int], tuple[float, float]] = {}
        self._outbox: list[Callable[[], None]] = []  # for the I/O thread, oldest first
        self._unsent = 0  # jobs queued or being sent
        self._outbox_cond = threading.Condition()
        self._next_any_due_ns = 0
        self._next_event_ns = 0
        self._next_fence_ns = 0
        self._last_key: tuple[FlightMode, bool] | None = None
        self._last_mission_state = (-2, -1)  # current item, mission_state last sent
        self._last_completed = False
        self._last_reached = -1
        self._fence_latched = False
        self._next_battery_ns = 0
        self._battery_level = battery.LEVEL_OK
        self.zones: tuple[Zone, ...] = ()
        self.last_fix: GpsFix | None = None

    def on_sample(self, sample: SimSample) -> None:
        """Queue what is due: events at once, streams by simulated time (capped in wall time)."""
        ep = self._ep
        ep.latest = sample
        tick = sample.camera
        if tick is not None and tick.capture_index is not None:
            ep.images_captured = tick.capture_index + 1
        if sample.gps is not None:
            self.last_fix = sample.gps
        ap = sample.autopilot
        t = sample.state.sim_time_ns
        key = (ap.mode, ap.armed)
        if key != self._last_key:
            self._last_key = key
            self._send(ep.send_heartbeat)
        self._mission_events(sample)
        if t >= self._next_event_ns:
            self._next_event_ns = t + EVENT_PERIOD_NS
            self._poll_events()
        if self.zones and t >= self._next_fence_ns:
            self._next_fence_ns = t + FENCE_PERIOD_NS
            self._check_fence(sample)
        if sample.battery is not None and t >= self._next_battery_ns:
            self._next_battery_ns = t + FENCE_PERIOD_NS
            self._check_battery(sample)
        if t >= self._next_any_due_ns:
            self._streams(sample, t)

    def _mission_events(self, sample: SimSample) -> None:
        """MISSION_CURRENT when the current item or the mission_state changed, then
        MISSION_ITEM_REACHED, in one job (one burst on the wire).

        The order is PX4's (MavlinkMissionManager::send: MISSION_CURRENT, then
        MISSION_ITEM_REACHED, for one mission result) and it matters at the end: MAVSDK reports
        progress (total, total) on the last MISSION_ITEM_REACHED and answers
        ``is_mission_finished`` from the last MISSION_CURRENT's mission_state, so the state
        COMPLETE must be on the wire first. Sent the other way round (as two jobs, which the I/O
        thread could send in two bursts), a client asking the moment progress reached its total
        could be told "not finished" on a loaded machine (issue 33).
        """
        ep, ap = self._ep, sample.autopilot
        total = len(ep.protocol.items(MissionType.MISSION))
        state = (ap.current_seq, tm.mission_state(sample, total))
        changed = state != self._last_mission_state
        reached: list[int] = []
        if ap.reached_seq >= 0:
            reached.append(ap.reached_seq)
        if ap.mission_completed and not self._last_completed:
            # MAVSDK counts a mission done when the last item is reached, DO items included.
            last = total - 1
            latest = reached[-1] if reached else self._last_reached
            if last >= 0 and latest != last:
                reached.append(last)
        self._last_mission_state, self._last_completed = state, ap.mission_completed
        self._last_reached = reached[-1] if reached else self._last_reached
        if not changed and not reached:
            return
        streams = self._message_streams

        def send() -> None:
            if changed:
                streams.send([mav.MAVLINK_MSG_ID_MISSION_CURRENT], sample, None)
            for seq in reached:
                ep.broadcast(mav.MAVLink_mission_item_reached_message(seq))

        self._send(send)

    def _poll_events(self) -> None:
        ap = self._ep.autopilot
        if ap is None:
            return
        for text in ap.pop_events():
            self._text(SEVERITY_INFO, text)

    def _streams(self, sample: SimSample, t: int) -> None:
        ep = self._ep
        now = time.monotonic()
        cap = ep.options.wall_cap_hz
        next_any = t + NS_PER_S
        for link, intervals in self._message_streams.tables.items():
            due: list[int] = []
            for msg_id, interval in intervals.items():
                if interval <= 0:
                    continue
                key = (id(link), msg_id)
                when = self._next_due.get(key, 0)
                if t >= when:
                    if cap is None or self._wall_token(key, now, max(cap, NS_PER_S / interval)):
                        due.append(msg_id)
                    # On time: keep the phase, so the rate holds whatever the physics step.
                    when = when + interval if t - when < interval else t + interval
                    self._next_due[key] = when
                next_any = min(next_any, when)
            if due:
                self._send(
                    functools.partial(
                        self._message_streams.send_on, link, due, sample, self.last_fix
                    )
                )
        self._next_any_due_ns = next_any

    def _send(self, job: Callable[[], None]) -> None:
        """Hand ``job`` (stream messages or an event) to the I/O thread, in order, with
        backpressure: jobs wait in one outbox that the I/O thread sends in one go; while
        MAX_PENDING_JOBS are unsent the simulation waits (as a lockstep PX4 SITL waits for its
        links), which releases the GIL. A CPU-bound simulation otherwise leaves the I/O thread
        the GIL so rarely that an unbounded queue grows and command ACKs behind it wait for tens
        of seconds. Every stream is still delivered in full, and in the order it happened."""
        with self._outbox_cond:
            while self._unsent >= MAX_PENDING_JOBS and self._ep.io_running:
                self._outbox_cond.wait(BACKPRESSURE_POLL_S)
            self._outbox.append(job)
            self._unsent += 1
            if len(self._outbox) > 1:
                return  # a flush is already queued
        self._ep.to_io(self._flush_outbox)

    def announce(self, severity: int, text: str) -> None:
        """A STATUSTEXT from the simulation thread, in order with the telemetry."""
        self._text(severity, text)

    def _text(self, severity: int, text: str) -> None:
        """A STATUSTEXT, in order with the telemetry."""
        self._send(lambda: self._ep.broadcast_text(severity, text))

    def _flush_outbox(self) -> None:
        with self._outbox_cond:
            jobs, self._outbox = self._outbox, []
        try:
            for job in jobs:
                self._ep.guard(job)
        finally:
            with self._outbox_cond:
                self._unsent -= len(jobs)
                self._outbox_cond.notify_all()

    def _wall_token(self, key: tuple[int, int], now: float, rate_hz: float) -> bool:
        """Token bucket in wall time: at most ``rate_hz`` on average, jitter tolerated."""
        burst = max(2.0, rate_hz * WALL_BURST_S)
        tokens, last = self._tokens.get(key, (burst, now))
        tokens = min(burst, tokens + (now - last) * rate_hz)
        if tokens >= 1.0:
            self._tokens[key] = (tokens - 1.0, now)
            return True
        self._tokens[key] = (tokens, now)
        return False

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
        self._text(SEVERITY_CRITICAL, f"Geofence breached ({why}): RTL")

    def _check_battery(self, sample: SimSample) -> None:
        """PX4's low-battery warnings and failsafe (COM_LOW_BAT_ACT), once per level."""
        ep, params = self._ep, self._ep.params
        if params is None or sample.battery is None:
            return
        level = battery.warning_level(
            sample.battery.remaining,
            params.get("BAT_LOW_THR"),
            params.get("BAT_CRIT_THR"),
            params.get("BAT_EMERGEN_THR"),
        )
        if level <= self._battery_level:
            return
        self._battery_level = level
        name = {battery.LEVEL_LOW: "Low", battery.LEVEL_CRITICAL: "Critical"}.get(
            level, "Emergency"
        )
        percent = sample.battery.remaining * 100
        action = battery.failsafe_action(level, round(params.get("COM_LOW_BAT_ACT")))
        ap, autopilot = sample.autopilot, ep.autopilot
        flying = ap.armed and not sample.state.on_ground
        if action == battery.ACTION_NONE or not flying or autopilot is None:
            self._text(SEVERITY_WARNING, f"{name} battery level: {percent:.0f}% remaining")
            return
        if action == battery.ACTION_RETURN and ap.mode not in (FlightMode.RTL, FlightMode.LAND):
            autopilot.return_to_launch()
            self._text(SEVERITY_CRITICAL, f"{name} battery level ({percent:.0f}%): RTL")
        elif action == battery.ACTION_LAND and ap.mode is not FlightMode.LAND:
            autopilot.set_mode(FlightMode.LAND)
            self._text(SEVERITY_CRITICAL, f"{name} battery level ({percent:.0f}%): landing")

    def on_frame(self, frame: CameraFrame) -> None:
        """Frames are not sent over MAVLink."""

    def close(self, result: FlightResult) -> None:
        """The flight ended: say so to the clients."""
        self._text(SEVERITY_INFO, "Simulation stopped")
