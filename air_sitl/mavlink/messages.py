"""Mission-protocol messages as plain typed values, independent of any MAVLink library.

The codec turns MISSION_* frames into these and back; the sans-IO state machine in
:mod:`air_sitl.mavlink.mission_protocol` consumes and produces only these.
"""

from __future__ import annotations

from dataclasses import dataclass

from air_sitl.mission.items import MissionItem, MissionType

MISSION_TYPE_ALL = 255  # MAV_MISSION_TYPE_ALL: only valid in MISSION_CLEAR_ALL


@dataclass(frozen=True, slots=True)
class Peer:
    """The MAVLink system and component on the other side of a transfer, and the route (link
    and address) it spoke from: two ground stations with the same ids (QGroundControl and
    MAVProxy both default to 255/190) on two routes are two peers, as PX4 keeps transfers per
    link."""

    system_id: int
    component_id: int
    route: int = 0


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionCount:
    """MISSION_COUNT: starts an upload (GCS -> vehicle) or answers a list request."""

    count: int
    mission_type: int = MissionType.MISSION
    opaque_id: int = 0


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionRequestList:
    """MISSION_REQUEST_LIST: starts a download."""

    mission_type: int = MissionType.MISSION


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionRequest:
    """MISSION_REQUEST_INT (``int_form``) or the deprecated float MISSION_REQUEST."""

    seq: int
    mission_type: int = MissionType.MISSION
    int_form: bool = True


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionItemMessage:
    """MISSION_ITEM_INT (``int_form``) or the deprecated float MISSION_ITEM."""

    seq: int
    item: MissionItem
    mission_type: int = MissionType.MISSION
    current: bool = False
    int_form: bool = True


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionAck:
    """MISSION_ACK: ends a transfer with a result."""

    result: int
    mission_type: int = MissionType.MISSION
    opaque_id: int = 0


@dataclass(frozen=True, slots=True, kw_only=True)
class MissionClearAll:
    """MISSION_CLEAR_ALL of one list, or of all three (``MISSION_TYPE_ALL``)."""

    mission_type: int = MissionType.MISSION


MissionMessage = (
    MissionCount
    | MissionRequestList
    | MissionRequest
    | MissionItemMessage
    | MissionAck
    | MissionClearAll
)
