"""MAVLink bytes <-> messages: the only module of the project that imports pymavlink.

:class:`Parser` turns received bytes into messages without ever raising, counting what it
drops; :class:`Encoder` packs messages (with MAVLink 2 signing when a key is set);
the mission converters map MISSION_* frames to the pure types of :mod:`messages`.
"""

from __future__ import annotations

import math
import struct
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from air_sitl.errors import MavlinkError
from air_sitl.mavlink import messages
from air_sitl.mission.items import GLOBAL_FRAMES, TERRAIN_FRAMES, MissionItem

mav = mavlink2  # the dialect module: message classes and enum constants for the other modules
Message = Any  # a pymavlink message object

_SIGNING_EPOCH_S = 1_420_070_400  # 2015-01-01, MAVLink 2 signing timestamps count 10 us from it
# Frames whose x/y travel as degE7 integers in MISSION_ITEM_INT.
_DEGE7_FRAMES = GLOBAL_FRAMES | TERRAIN_FRAMES


def load_signing_key(text: str) -> bytes:
    """``--signing-key``: 64 hex digits, or ``@FILE`` holding them (or 32 raw bytes)."""
    source = "--signing-key"
    raw = text.strip()
    if raw.startswith("@"):
        path = Path(raw[1:])
        source = f"--signing-key {path}"
        try:
            data = path.read_bytes()
        except OSError as err:
            msg = f"{source}: cannot read the key file: {err.strerror}"
            raise MavlinkError(msg) from None
        if len(data) == 32 and not _is_hex(data.strip()):
            return data
        raw = data.decode("ascii", errors="replace").strip()
    if len(raw) != 64 or not _is_hex(raw.encode("ascii", errors="replace")):
        msg = f"{source}: expected 64 hex digits (a 32-byte key), got {len(raw)} characters"
        raise MavlinkError(msg)
    return bytes.fromhex(raw)


def _is_hex(data: bytes) -> bool:
    return all(c in b"0123456789abcdefABCDEF" for c in data) and len(data) > 0


def _now_signing_timestamp() -> int:
    return int((time.time() - _SIGNING_EPOCH_S) * 100_000)


class Signing:
    """One MAVLink 2 signing state shared by every parser and encoder of the vehicle.

    Sharing it makes replay detection work across links and peers: a timestamp at or below the
    last one seen on a (link id, system, component) stream is refused wherever it arrives.
    """

    def __init__(self, key: bytes) -> None:
        state = mavlink2.MAVLinkSigning()
        state.secret_key = key
        state.sign_outgoing = True
        state.link_id = 0
        state.timestamp = _now_signing_timestamp()
        state.allow_unsigned_callback = _allow_unsigned
        self.state = state
        self.replayed = 0


def _allow_unsigned(_mav: Any, msg_id: int) -> bool:
    # Only RADIO_STATUS may come unsigned (radios inject it); everything else is dropped.
    return bool(msg_id == mavlink2.MAVLINK_MSG_ID_RADIO_STATUS)


@dataclass(slots=True)
class ParseCounters:
    """What a parser kept and dropped (all links of a vehicle add theirs together)."""

    messages: int = 0
    parse_errors: int = 0  # bad CRC, bad prefix, bad length, truncated, bad incompat flags
    unknown_ids: int = 0  # a valid frame of a message this dialect does not know
    signature_rejected: int = 0  # unsigned, MAVLink 1 or bad signature while signing is on
    replayed: int = 0  # signed with an old timestamp (counted in signature_rejected too)
    kernel_dropped: int = 0  # datagrams the kernel dropped, its buffer full (Linux tells)
    kernel_drops_counted: bool = False  # a UDP link could read the kernel's drop count

    @property
    def dropped(self) -> int:
        """Frames that did not become a message."""
        return self.parse_errors + self.unknown_ids + self.signature_rejected


class Parser:
    """Bytes from one peer (a UDP address or a TCP connection) to messages; never raises."""

    def __init__(self, counters: ParseCounters, signing: Signing | None = None) -> None:
        self._counters = counters
        self._signing = signing
        self._mav = self._new()

    @property
    def counters(self) -> ParseCounters:
        """The counters this parser adds to (shared by every link of the vehicle)."""
        return self._counters

    def _new(self) -> Any:
        m = mavlink2.MAVLink(None, 0, 0)
        m.robust_parsing = True
        if self._signing is not None:
            m.signing = self._signing.state
            original = m.check_signature
            signing = self._signing

            def check(msgbuf: bytearray, src_system: int, src_component: int) -> bool:
                link_id = msgbuf[-13]
                tlow, thigh = struct.unpack("<IH", bytes(msgbuf[-12:-6]))
                stamp = tlow + (thigh << 32)
                seen = signing.state.stream_timestamps.get((link_id, src_system, src_component))
                ok = bool(original(msgbuf, src_system, src_component))
                if not ok and seen is not None and stamp <= seen:
                    signing.replayed += 1
                    self._counters.replayed += 1
                return ok

            m.check_signature = check
        return m

    def feed(self, data: bytes, *, datagram: bool = False) -> list[Message]:
        """Messages completed by ``data``. A datagram never leaves bytes for the next one."""
        out: list[Message] = []
        try:
            found = self._mav.parse_buffer(data)
        except Exception:  # pymavlink raises on a few malformed inputs despite robust parsing
            self._counters.parse_errors += 1
            self._mav = self._new()
            return out
        for msg in found or ():
            msg_id = msg.get_msgId()
            if msg_id == mavlink2.MAVLINK_MSG_ID_BAD_DATA:
                if getattr(msg, "reason", "") == "Invalid signature":
                    self._counters.signature_rejected += 1
                else:
                    self._counters.parse_errors += 1
            elif msg_id == mavlink2.MAVLINK_MSG_ID_UNKNOWN:
                self._counters.unknown_ids += 1
            else:
                self._counters.messages += 1
                out.append(msg)
        if datagram and self._mav.buf_len() > 0:
            self._counters.parse_errors += 1  # a frame cut short inside the datagram
            self._mav.buf = bytearray()
            self._mav.buf_index = 0
            self._mav.expected_length = mavlink2.HEADER_LEN_V1 + 2
        return out


class _Capture:
    def __init__(self) -> None:
        self.data = b""

    def write(self, data: bytes) -> None:
        self.data = bytes(data)


class Encoder:
    """Packs messages as MAVLink 2 from one system/component, with its own sequence numbers."""

    def __init__(self, system_id: int, component_id: int, signing: Signing | None = None) -> None:
        self._capture = _Capture()
        self._mav = mavlink2.MAVLink(self._capture, system_id, component_id)
        if signing is not None:
            self._mav.signing = signing.state

    @property
    def mav(self) -> Any:
        """The pymavlink object, for its ``*_encode`` message constructors."""
        return self._mav

    def encode(self, msg: Message) -> bytes:
        """The frame bytes of ``msg`` (advances the sequence number)."""
        self._mav.send(msg)
        return self._capture.data


# --- mission messages -------------------------------------------------------------------------


def _int32(value: float) -> int:
    if not math.isfinite(value):
        return 0
    return max(-(2**31), min(2**31 - 1, round(value)))


def item_from_int(
    frame: int,
    command: int,
    p: tuple[float, float, float, float],
    xyz: tuple[int, int, float],
    autocontinue: int,
    seq: int,
) -> MissionItem:
    """A MissionItem from MISSION_ITEM_INT fields (x, y in degE7 for global frames)."""
    scale = 1e-7 if frame in _DEGE7_FRAMES else 1.0
    return MissionItem.from_params(
        command,
        frame,
        (*p, xyz[0] * scale, xyz[1] * scale, xyz[2]),
        autocontinue=bool(autocontinue),
        seq=seq,
    )


def to_mission_message(msg: Message) -> messages.MissionMessage | None:
    """The mission-protocol value of a MISSION_* message, None for any other message."""
    name = msg.get_type()
    mission_type = getattr(msg, "mission_type", 0)
    if name == "MISSION_COUNT":
        return messages.MissionCount(
            count=msg.count, mission_type=mission_type, opaque_id=getattr(msg, "opaque_id", 0)
        )
    if name == "MISSION_REQUEST_LIST":
        return messages.MissionRequestList(mission_type=mission_type)
    if name in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
        return messages.MissionRequest(
            seq=msg.seq, mission_type=mission_type, int_form=name == "MISSION_REQUEST_INT"
        )
    if name == "MISSION_ITEM_INT":
        p = (msg.param1, msg.param2, msg.param3, msg.param4)
        xyz = (msg.x, msg.y, msg.z)
        item = item_from_int(msg.frame, msg.command, p, xyz, msg.autocontinue, msg.seq)
        return messages.MissionItemMessage(
            seq=msg.seq, item=item, mission_type=mission_type, current=bool(msg.current)
        )
    if name == "MISSION_ITEM":
        item = MissionItem.from_params(
            msg.command,
            msg.frame,
            (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z),
            autocontinue=bool(msg.autocontinue),
            seq=msg.seq,
        )
        return messages.MissionItemMessage(
            seq=msg.seq, item=item, mission_type=mission_type, current=bool(msg.current),
            int_form=False,
        )  # fmt: skip
    if name == "MISSION_ACK":
        return messages.MissionAck(
            result=msg.type, mission_type=mission_type, opaque_id=getattr(msg, "opaque_id", 0)
        )
    if name == "MISSION_CLEAR_ALL":
        return messages.MissionClearAll(mission_type=mission_type)
    return None


def from_mission_message(
    m: messages.MissionMessage, target_system: int, target_component: int
) -> Message:
    """The pymavlink message for a mission-protocol value addressed to the target."""
    t = (target_system, target_component)
    if isinstance(m, messages.MissionCount):
        return mavlink2.MAVLink_mission_count_message(*t, m.count, m.mission_type)
    if isinstance(m, messages.MissionRequestList):
        return mavlink2.MAVLink_mission_request_list_message(*t, m.mission_type)
    if isinstance(m, messages.MissionRequest):
        cls = (
            mavlink2.MAVLink_mission_request_int_message
            if m.int_form
            else mavlink2.MAVLink_mission_request_message
        )
        return cls(*t, m.seq, m.mission_type)
    if isinstance(m, messages.MissionItemMessage):
        i = m.item
        p = i.params[:4]
        if m.int_form:
            scale = 1e7 if i.frame in _DEGE7_FRAMES else 1.0
            return mavlink2.MAVLink_mission_item_int_message(
                *t, m.seq, i.frame, i.command, int(m.current), int(i.autocontinue), *p,
                _int32(i.lat_deg * scale), _int32(i.lon_deg * scale), i.alt_m, m.mission_type,
            )  # fmt: skip
        return mavlink2.MAVLink_mission_item_message(
            *t, m.seq, i.frame, i.command, int(m.current), int(i.autocontinue), *p,
            i.lat_deg, i.lon_deg, i.alt_m, m.mission_type,
        )  # fmt: skip
    if isinstance(m, messages.MissionAck):
        return mavlink2.MAVLink_mission_ack_message(*t, m.result, m.mission_type)
    return mavlink2.MAVLink_mission_clear_all_message(*t, m.mission_type)
