"""What the parts of the MAVLink vehicle share: the endpoint as its parts see it
(:class:`EndpointLike`), the autopilot, parameter and video protocols they drive, the job and
handler types, their base class, STATUSTEXT severities and small parameter helpers.

Imports point one way: :mod:`vehicle` builds the endpoint from its parts (camera, commands,
streams, parameters, FTP, the navigation link), and the parts know the endpoint only through
:class:`EndpointLike` here, never by importing :mod:`vehicle`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Message, ParseCounters, mav
from air_sitl.mavlink.links import Channel, Link
from air_sitl.mavlink.mission_protocol import MissionProtocol
from air_sitl.mission.items import Mission
from air_sitl.state import FlightMode, GeoPoint, GpsFix, SimSample

NS_PER_S = 1_000_000_000
WALL_CAP_HZ = 200.0  # no stream goes faster than max(this, its own rate) in wall time
SEVERITY_CRITICAL, SEVERITY_ERROR, SEVERITY_WARNING, SEVERITY_INFO = 2, 3, 4, 6


class AutopilotLike(Protocol):
    """The autopilot commands the endpoint uses (run on the simulation thread only)."""

    def arm(self) -> Any: ...
    def disarm(self) -> Any: ...
    def set_mode(self, mode: FlightMode) -> Any: ...
    def start_mission(self) -> Any: ...
    def set_mission(self, mission: Mission, current_seq: int | None = None) -> Any: ...
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


class VideoStreamLike(Protocol):
    """The camera's video stream, as the camera component describes and drives it
    (``air_sitl.video.stream.VideoStream``); called from the I/O thread."""

    @property
    def streaming(self) -> bool: ...
    @property
    def fps(self) -> float: ...
    @property
    def bitrate_bps(self) -> int: ...
    @property
    def uri(self) -> str: ...
    def start(self) -> None: ...
    def stop(self) -> None: ...


Job = Callable[[AutopilotLike], None]  # runs on the simulation thread
PostFn = Callable[[Job], None]
# An incoming-message handler, run on the I/O thread: (the peer's channel, the message).
Handler = Callable[[Channel, Message], None]
# Builds one message from the latest sample and GNSS fix; None when it cannot be built yet.
Builder = Callable[[SimSample | None, GpsFix | None], Message | None]


@dataclass(frozen=True, slots=True, kw_only=True)
class EndpointOptions:
    """Identity and behaviour of the endpoint."""

    system_id: int = 1
    component_id: int = mav.MAV_COMP_ID_AUTOPILOT1
    signing_key: bytes | None = None
    wall_cap_hz: float | None = WALL_CAP_HZ  # None: rates in simulated time, uncapped
    camera: tm.CameraInfo | None = None  # None: no camera component (component id 100)
    video: VideoStreamLike | None = None  # the camera's video stream (needs ``camera``)
    terrain: bool = False  # a terrain model (--dem): uploads may use terrain-relative frames


class StreamsLike(Protocol):
    """The endpoint's message streams, as the command handlers and the navigation link use
    them (:class:`air_sitl.mavlink.streams.Streams`)."""

    def add(self, msg_id: int, builder: Builder, rate_hz: float = 0.0) -> None: ...
    def build(
        self, msg_id: int, sample: SimSample | None, fix: GpsFix | None
    ) -> Message | None: ...
    def set_interval(self, link: Link, msg_id: int, interval_us: float) -> bool: ...
    def request_data_stream(
        self, link: Link, stream_id: int, rate_hz: int, start: bool
    ) -> None: ...
    def send(self, ids: Sequence[int], sample: SimSample | None, fix: GpsFix | None) -> None: ...


class FixHolder(Protocol):
    """What keeps the latest GNSS fix (the telemetry sink)."""

    @property
    def last_fix(self) -> GpsFix | None: ...


class EndpointLike(Protocol):
    """The vehicle endpoint as its parts see it (:class:`air_sitl.mavlink.vehicle.
    VehicleEndpoint`): its identity, the latest state, and the ways to send and to run jobs."""

    latest: SimSample | None  # the newest sample (written by the telemetry sink)
    images_captured: int  # capture-window frames so far (written by the telemetry sink)

    @property
    def options(self) -> EndpointOptions: ...
    @property
    def home(self) -> GeoPoint: ...
    @property
    def autopilot(self) -> AutopilotLike | None: ...
    @property
    def params(self) -> ParamsLike | None: ...
    @property
    def protocol(self) -> MissionProtocol: ...
    @property
    def counters(self) -> ParseCounters: ...
    @property
    def streams(self) -> StreamsLike: ...
    @property
    def sink(self) -> FixHolder: ...
    @property
    def io_running(self) -> bool: ...
    def register(self, message_type: str, handler: Handler) -> None: ...
    def reply(self, ch: Channel, msg: Message) -> None: ...
    def broadcast(self, msg: Message) -> None: ...
    def reply_text(self, ch: Channel, severity: int, text: str) -> None: ...
    def broadcast_text(self, severity: int, text: str) -> None: ...
    def text(self, severity: int, text: str) -> None: ...
    def send_heartbeat(self) -> None: ...
    def to_io(self, fn: Callable[[], None]) -> None: ...
    def guard(self, fn: Callable[[], None]) -> None: ...
    def post(self, job: Job) -> None: ...
    def on_sim(self, job: Job) -> None: ...


class EndpointPart:
    """One part of a vehicle endpoint (commands, parameters, FTP): the messages it answers."""

    def __init__(self, ep: EndpointLike) -> None:
        self._ep = ep

    def handlers(self) -> dict[str, Handler]:
        """Message type -> its handler, for every message this part answers."""
        raise NotImplementedError


def whole(value: float) -> int:
    """A command parameter as an integer; -1 for NaN or infinity."""
    return round(value) if math.isfinite(value) else -1


def outcome(value: Any) -> tuple[bool, str]:
    """Normalise what an autopilot command returned: None/True, False, or (ok, reason)."""
    if isinstance(value, tuple) and len(value) == 2:
        return bool(value[0]), str(value[1] or "")
    if value is None:
        return True, ""
    return bool(value), ""
