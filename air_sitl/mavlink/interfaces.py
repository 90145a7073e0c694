"""What the parts of the MAVLink vehicle share: the autopilot and parameter protocols they
drive, the job and handler types, their base class, STATUSTEXT severities and small parameter
helpers.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from air_sitl.mavlink.codec import Message
from air_sitl.mavlink.links import Channel
from air_sitl.mission.items import Mission
from air_sitl.state import FlightMode

if TYPE_CHECKING:  # the endpoint is made of the parts below: a real cycle
    from air_sitl.mavlink.vehicle import VehicleEndpoint

NS_PER_S = 1_000_000_000
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


Job = Callable[[AutopilotLike], None]  # runs on the simulation thread
PostFn = Callable[[Job], None]
# An incoming-message handler, run on the I/O thread: (the peer's channel, the message).
Handler = Callable[[Channel, Message], None]


class EndpointPart:
    """One part of a vehicle endpoint (commands, parameters, FTP): the messages it answers."""

    def __init__(self, ep: VehicleEndpoint) -> None:
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
