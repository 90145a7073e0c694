"""MissionItem: the one type that plan files and MAVLink mission uploads both produce.

Positions are stored as floats in degrees and metres; MAVLink scaled integers (degE7) are
converted only in the mavlink package. For commands that are not positions (DO_*), the
``lat_deg``/``lon_deg``/``alt_m`` fields carry raw params 5..7 unchanged.
"""

from __future__ import annotations

import enum
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from air_sitl.state import GeoPoint


class MavCmd(enum.IntEnum):
    """The MAV_CMD values this project knows (MAVLink common.xml)."""

    NAV_WAYPOINT = 16
    NAV_LOITER_UNLIM = 17
    NAV_LOITER_TURNS = 18
    NAV_LOITER_TIME = 19
    NAV_RETURN_TO_LAUNCH = 20
    NAV_LAND = 21
    NAV_TAKEOFF = 22
    NAV_LOITER_TO_ALT = 31
    NAV_SPLINE_WAYPOINT = 82
    NAV_VTOL_TAKEOFF = 84
    NAV_VTOL_LAND = 85
    NAV_DELAY = 93
    DO_SET_MODE = 176
    DO_JUMP = 177
    DO_CHANGE_SPEED = 178
    DO_SET_HOME = 179
    DO_LAND_START = 189
    DO_REPOSITION = 192
    DO_DIGICAM_CONTROL = 203
    DO_MOUNT_CONTROL = 205
    DO_SET_CAM_TRIGG_DIST = 206
    DO_PARACHUTE = 208
    DO_GRIPPER = 211
    DO_SET_MISSION_CURRENT = 224
    COMPONENT_ARM_DISARM = 400
    MISSION_START = 300
    SET_MESSAGE_INTERVAL = 511
    REQUEST_MESSAGE = 512
    SET_CAMERA_MODE = 530
    IMAGE_START_CAPTURE = 2000
    IMAGE_STOP_CAPTURE = 2001
    NAV_FENCE_RETURN_POINT = 5000
    NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
    NAV_FENCE_POLYGON_VERTEX_EXCLUSION = 5002
    NAV_FENCE_CIRCLE_INCLUSION = 5003
    NAV_FENCE_CIRCLE_EXCLUSION = 5004
    NAV_RALLY_POINT = 5100


# Commands the mission executor flies; anything else in a mission is refused at load time,
# except SKIPPED_COMMANDS (accepted, not executed, one warning per item).
NAV_COMMANDS = frozenset(
    {
        MavCmd.NAV_WAYPOINT,
        MavCmd.NAV_SPLINE_WAYPOINT,
        MavCmd.NAV_DELAY,
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LOITER_TURNS,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_RETURN_TO_LAUNCH,
        MavCmd.NAV_LAND,
        MavCmd.NAV_TAKEOFF,
        MavCmd.NAV_LOITER_TO_ALT,
    }
)
DO_COMMANDS = frozenset(
    {
        MavCmd.DO_CHANGE_SPEED,
        MavCmd.DO_JUMP,
        MavCmd.IMAGE_START_CAPTURE,
        MavCmd.IMAGE_STOP_CAPTURE,
        MavCmd.DO_LAND_START,
        MavCmd.DO_SET_CAM_TRIGG_DIST,
        MavCmd.DO_DIGICAM_CONTROL,
    }
)
# Payload and camera-setup items with no flight meaning here: skipped, and why.
SKIPPED_COMMANDS: dict[MavCmd, str] = {
    MavCmd.DO_MOUNT_CONTROL: "the camera is fixed, pointing down (no gimbal)",
    MavCmd.DO_GRIPPER: "the aircraft has no gripper",
    MavCmd.DO_PARACHUTE: "the aircraft has no parachute",
    MavCmd.SET_CAMERA_MODE: "the camera has one mode (still frames)",
}
MISSION_COMMANDS = NAV_COMMANDS | DO_COMMANDS | frozenset(SKIPPED_COMMANDS)
# Flown as a waypoint: a spline waypoint is flown on straight legs (see docs/flights.md).
WAYPOINT_COMMANDS = frozenset({MavCmd.NAV_WAYPOINT, MavCmd.NAV_SPLINE_WAYPOINT})
# Capture control items (camera section of a plan, survey trigger items).
CAPTURE_COMMANDS = frozenset(
    {
        MavCmd.IMAGE_START_CAPTURE,
        MavCmd.IMAGE_STOP_CAPTURE,
        MavCmd.DO_SET_CAM_TRIGG_DIST,
        MavCmd.DO_DIGICAM_CONTROL,
    }
)
LOITER_COMMANDS = frozenset(
    {
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LOITER_TURNS,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_LOITER_TO_ALT,
    }
)
FENCE_COMMANDS = frozenset(
    {
        MavCmd.NAV_FENCE_RETURN_POINT,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_EXCLUSION,
    }
)
# (inclusion, exclusion): fence polygon vertices and fence circles.
FENCE_POLYGON_COMMANDS = (
    MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
)
FENCE_CIRCLE_COMMANDS = (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION)
RALLY_COMMANDS = frozenset({MavCmd.NAV_RALLY_POINT})


class MavFrame(enum.IntEnum):
    """MAV_FRAME values for mission items."""

    GLOBAL = 0  # altitude AMSL
    MISSION = 2  # no position (DO_* items)
    GLOBAL_RELATIVE_ALT = 3  # altitude above home
    GLOBAL_INT = 5
    GLOBAL_RELATIVE_ALT_INT = 6
    GLOBAL_TERRAIN_ALT = 10
    GLOBAL_TERRAIN_ALT_INT = 11


# Frames with a latitude and longitude: altitude AMSL or above home (GLOBAL_FRAMES, the ones
# flown), above home (RELATIVE_FRAMES), above the terrain (TERRAIN_FRAMES, refused).
GLOBAL_FRAMES = frozenset(
    {
        MavFrame.GLOBAL,
        MavFrame.GLOBAL_RELATIVE_ALT,
        MavFrame.GLOBAL_INT,
        MavFrame.GLOBAL_RELATIVE_ALT_INT,
    }
)
RELATIVE_FRAMES = frozenset({MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT})
TERRAIN_FRAMES = frozenset({MavFrame.GLOBAL_TERRAIN_ALT, MavFrame.GLOBAL_TERRAIN_ALT_INT})


class MissionType(enum.IntEnum):
    """MAV_MISSION_TYPE: the three lists a vehicle stores separately."""

    MISSION = 0
    FENCE = 1
    RALLY = 2


class MissionResult(enum.IntEnum):
    """MAV_MISSION_RESULT: how a vehicle answers a mission upload (and validation names it)."""

    ACCEPTED = 0
    ERROR = 1
    UNSUPPORTED_FRAME = 2
    UNSUPPORTED = 3
    NO_SPACE = 4
    INVALID = 5
    INVALID_PARAM1 = 6
    INVALID_PARAM2 = 7
    INVALID_PARAM3 = 8
    INVALID_PARAM4 = 9
    INVALID_PARAM5_X = 10
    INVALID_PARAM6_Y = 11
    INVALID_PARAM7 = 12
    INVALID_SEQUENCE = 13
    DENIED = 14
    OPERATION_CANCELLED = 15


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionItem:
    """One mission item, as in MISSION_ITEM_INT / a QGC SimpleItem.

    ``param1..param4`` may be NaN (QGC writes ``null``). ``do_jump_id`` is QGC's doJumpId
    (DO_JUMP's param1 refers to it in .plan files; in MAVLink uploads it equals seq + 1).
    """

    command: int
    frame: int = MavFrame.GLOBAL_RELATIVE_ALT
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = math.nan
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    alt_m: float = 0.0
    autocontinue: bool = True
    do_jump_id: int = 0

    @classmethod
    def from_params(
        cls,
        command: int,
        frame: int,
        params: Sequence[float],
        *,
        autocontinue: bool,
        seq: int,
    ) -> MissionItem:
        """An item from MAVLink's seven params (5..7 = x/lat, y/lon, z/alt) at index ``seq``."""
        p1, p2, p3, p4, x, y, z = params
        return cls(
            command=command,
            frame=frame,
            param1=p1,
            param2=p2,
            param3=p3,
            param4=p4,
            lat_deg=x,
            lon_deg=y,
            alt_m=z,
            autocontinue=autocontinue,
            do_jump_id=seq + 1,
        )

    @property
    def params(self) -> tuple[float, float, float, float, float, float, float]:
        """MAVLink's seven params (5..7 = x/lat, y/lon, z/alt): what :meth:`from_params` takes."""
        return (
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.lat_deg,
            self.lon_deg,
            self.alt_m,
        )

    @property
    def is_nav(self) -> bool:
        """True for items with a position the aircraft flies to or around."""
        return self.command in NAV_COMMANDS


@dataclass(frozen=True, slots=True, kw_only=True)
class Mission:
    """A mission plan: the three MAVLink lists plus what QGC stores beside them."""

    items: tuple[MissionItem, ...]
    planned_home: GeoPoint | None = None
    cruise_speed_m_s: float = 15.0
    fence: tuple[MissionItem, ...] = ()
    rally: tuple[MissionItem, ...] = ()
    source: str = "<memory>"  # file path or "mavlink upload": used in error messages
    name: str = field(default="")  # scenario name, e.g. "FL-200" (file stem)
    notes: tuple[str, ...] = ()  # warnings found when reading the file (vehicleType, ...)
