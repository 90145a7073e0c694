"""Vehicle side of the MAVLink mission protocol as a sans-IO state machine.

Messages and a monotonic clock go in, messages (and "list replaced" events) come out; no
sockets, no threads, no MAVLink library. Mission, fence and rally lists are stored separately.
An upload replaces a list only once every item arrived and the whole list validated; any error,
cancel or timeout leaves the stored list untouched (atomic replacement). Timeouts follow
mavlink.io's Mission Protocol: an item request is re-sent after 250 ms, at most 5 times.

This is the edge where uploaded lists are validated (:mod:`air_sitl.mission.validate`), as
``load_mission`` is for plan files: what flies a replaced list trusts it.
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass, field

from air_sitl.mavlink.messages import (
    MISSION_TYPE_ALL,
    MissionAck,
    MissionClearAll,
    MissionCount,
    MissionItemMessage,
    MissionMessage,
    MissionRequest,
    MissionRequestList,
    Peer,
)
from air_sitl.mission.items import MissionItem, MissionResult, MissionType
from air_sitl.mission.validate import ItemProblem, check_item, check_mission

ITEM_TIMEOUT_NS = 250_000_000  # re-request a missing item after this long
DEFAULT_TIMEOUT_NS = 1_500_000_000  # mavlink.io default timeout (a GCS waiting for an answer)
MAX_RETRIES = 5
MAX_ITEMS: dict[MissionType, int] = {
    MissionType.MISSION: 5000,
    MissionType.FENCE: 500,
    MissionType.RALLY: 50,
}


@dataclass(frozen=True, slots=True)
class Send:
    """A message for ``peer``."""

    peer: Peer
    message: MissionMessage


@dataclass(frozen=True, slots=True)
class Replaced:
    """A stored list changed (upload completed or cleared): the vehicle must use ``items``.

    ``current_seq``: the item the ground station flagged current, -1 for none (PX4 then keeps
    its current index). ``changed``: False when the upload had the stored items exactly.
    """

    mission_type: MissionType
    items: tuple[MissionItem, ...]
    current_seq: int = -1
    changed: bool = True


@dataclass(frozen=True, slots=True)
class Failed:
    """An upload ended without replacing the list (the reason, for STATUSTEXT and counters)."""

    mission_type: MissionType
    result: MissionResult
    reason: str


Output = Send | Replaced | Failed


def opaque_id_of(items: Sequence[MissionItem]) -> int:
    """A non-zero 32-bit id of a list's content (MISSION_ACK/COUNT ``opaque_id``)."""
    crc = 0
    for item in items:
        packed = struct.pack(
            "<HBffffdddB",
            item.command & 0xFFFF,
            item.frame & 0xFF,
            *item.params,
            int(item.autocontinue),
        )
        crc = zlib.crc32(packed, crc)
    return crc or 1


def _result_of(problem: ItemProblem) -> MissionResult:
    try:
        return problem.result_code
    except KeyError:
        return MissionResult.ERROR


@dataclass(slots=True)
class _Upload:
    peer: Peer
    mission_type: MissionType
    count: int
    int_form: bool = True
    items: list[MissionItem] = field(default_factory=list)
    last_request_ns: int = 0
    retries: int = 0
    current_seq: int = -1  # the item flagged current, -1 for none


@dataclass(slots=True)
class _Done:
    """The last finished upload, to re-send its ACK if the GCS re-sends the last item."""

    peer: Peer
    mission_type: MissionType
    count: int
    ack: MissionAck


class MissionProtocol:
    """Stores the three lists and runs at most one upload at a time."""

    def __init__(
        self,
        *,
        mission: Sequence[MissionItem] = (),
        fence: Sequence[MissionItem] = (),
        rally: Sequence[MissionItem] = (),
        item_timeout_ns: int = ITEM_TIMEOUT_NS,
        max_retries: int = MAX_RETRIES,
        terrain: bool = False,
    ) -> None:
        self._terrain = terrain  # a terrain model (--dem): terrain-relative frames are accepted
        self._stores: dict[MissionType, tuple[MissionItem, ...]] = {
            MissionType.MISSION: tuple(mission),
            MissionType.FENCE: tuple(fence),
            MissionType.RALLY: tuple(rally),
        }
        self._opaque = {t: opaque_id_of(items) for t, items in self._stores.items()}
        self._item_timeout_ns = item_timeout_ns
        self._max_retries = max_retries
        self._upload: _Upload | None = None
        self._done: _Done | None = None

    # --- read side ------------------------------------------------------------------------

    def items(self, mission_type: MissionType) -> tuple[MissionItem, ...]:
        """The stored list of ``mission_type``."""
        return self._stores[mission_type]

    def opaque_id(self, mission_type: MissionType) -> int:
        """The content id of the stored list (MISSION_CURRENT ``mission_id`` for missions)."""
        return self._opaque[mission_type]

    @property
    def busy(self) -> bool:
        """True while an upload is in progress."""
        return self._upload is not None

    # --- input ----------------------------------------------------------------------------

    def handle(self, peer: Peer, message: MissionMessage, now_ns: int) -> list[Output]:
        """Process one message from ``peer`` received at ``now_ns``."""
        if isinstance(message, MissionCount):
            return self._on_count(peer, message, now_ns)
        if isinstance(message, MissionItemMessage):
            return self._on_item(peer, message, now_ns)
        if isinstance(message, MissionRequestList):
            return self._on_request_list(peer, message)
        if isinstance(message, MissionRequest):
            return self._on_request(peer, message)
        if isinstance(message, MissionClearAll):
            return self._on_clear(peer, message)
        return self._on_ack(peer, message)

    def tick(self, now_ns: int) -> list[Output]:
        """Re-send a missing item request, or give the upload up after the last retry."""
        up = self._upload
        if up is None or now_ns - up.last_request_ns < self._item_timeout_ns:
            return []
        if up.retries >= self._max_retries:
            self._upload = None
            return [
                Send(up.peer, MissionAck(result=MissionResult.OPERATION_CANCELLED,
                                         mission_type=up.mission_type)),
                Failed(up.mission_type, MissionResult.OPERATION_CANCELLED,
                       f"upload timed out waiting for item {len(up.items)}"),
            ]  # fmt: skip
        up.retries += 1
        return [self._request_next(up, now_ns)]

    # --- handlers -------------------------------------------------------------------------

    @staticmethod
    def _mission_type(value: int) -> MissionType | None:
        try:
            return MissionType(value)
        except ValueError:
            return None

    def _ack(self, peer: Peer, result: MissionResult, mission_type: int) -> Send:
        return Send(peer, MissionAck(result=result, mission_type=mission_type))

    def _request_next(self, up: _Upload, now_ns: int) -> Send:
        up.last_request_ns = now_ns
        seq = len(up.items)
        return Send(
            up.peer, MissionRequest(seq=seq, mission_type=up.mission_type, int_form=up.int_form)
        )

    def _on_count(self, peer: Peer, msg: MissionCount, now_ns: int) -> list[Output]:
        mission_type = self._mission_type(msg.mission_type)
        if mission_type is None:
            return [self._ack(peer, MissionResult.UNSUPPORTED, msg.mission_type)]
        up = self._upload
        if up is not None and up.peer != peer:
            return [self._ack(peer, MissionResult.DENIED, mission_type)]
        same = up is not None and (up.mission_type, up.count) == (mission_type, msg.count)
        if up is not None and same and not up.items:
            return [self._request_next(up, now_ns)]  # our first request was lost: count again
        self._upload = None
        if msg.count > MAX_ITEMS[mission_type] or msg.count < 0:
            return [
                self._ack(peer, MissionResult.NO_SPACE, mission_type),
                Failed(mission_type, MissionResult.NO_SPACE,
                       f"{msg.count} items, at most {MAX_ITEMS[mission_type]} fit"),
            ]  # fmt: skip
        if msg.count == 0:
            return self._finish(peer, mission_type, [])
        up = _Upload(peer=peer, mission_type=mission_type, count=msg.count)
        self._upload = up
        self._done = None
        return [self._request_next(up, now_ns)]

    def _on_item(self, peer: Peer, msg: MissionItemMessage, now_ns: int) -> list[Output]:
        up = self._upload
        if up is None or up.peer != peer or msg.mission_type != up.mission_type:
            done = self._done
            if (
                up is None
                and done is not None
                and done.peer == peer
                and done.mission_type == msg.mission_type
                and msg.seq == done.count - 1
            ):
                return [Send(peer, done.ack)]  # our final ACK was lost
            return []
        expected = len(up.items)
        if msg.seq >= up.count:
            self._upload = None
            return [
                self._ack(peer, MissionResult.INVALID_SEQUENCE, up.mission_type),
                Failed(up.mission_type, MissionResult.INVALID_SEQUENCE,
                       f"item {msg.seq} of a {up.count}-item upload"),
            ]  # fmt: skip
        if msg.seq < expected:
            return []  # a duplicate of an item we already have
        if msg.seq > expected:
            return [self._request_next(up, now_ns)]  # out of order: ask again for ours
        problem = check_item(msg.item, msg.seq, up.mission_type, terrain=self._terrain)
        if problem is not None:
            self._upload = None
            result = _result_of(problem)
            return [
                self._ack(peer, result, up.mission_type),
                Failed(up.mission_type, result, f"item {msg.seq}: {problem.message}"),
            ]
        up.int_form = msg.int_form  # answer an old-style client in its own form
        if msg.current:
            up.current_seq = msg.seq
        up.items.append(msg.item)
        up.retries = 0
        if len(up.items) < up.count:
            return [self._request_next(up, now_ns)]
        self._upload = None
        return self._finish(peer, up.mission_type, up.items, up.current_seq)

    def _finish(
        self,
        peer: Peer,
        mission_type: MissionType,
        items: list[MissionItem],
        current_seq: int = -1,
    ) -> list[Output]:
        candidate = tuple(items)
        problem = check_mission(candidate, mission_type, allow_empty=True, terrain=self._terrain)
        if problem is not None:
            result = _result_of(problem)
            ack = MissionAck(result=result, mission_type=mission_type)
            self._done = _Done(peer, mission_type, len(candidate), ack)
            where = f"item {problem.index}: " if problem.index >= 0 else ""
            return [Send(peer, ack), Failed(mission_type, result, where + problem.message)]
        changed = _wire_key(self._stores[mission_type]) != _wire_key(candidate)
        self._stores[mission_type] = candidate
        self._opaque[mission_type] = opaque_id_of(candidate)
        ack = MissionAck(
            result=MissionResult.ACCEPTED,
            mission_type=mission_type,
            opaque_id=self._opaque[mission_type],
        )
        self._done = _Done(peer, mission_type, len(candidate), ack)
        return [Send(peer, ack), Replaced(mission_type, candidate, current_seq, changed)]

    def _on_request_list(self, peer: Peer, msg: MissionRequestList) -> list[Output]:
        mission_type = self._mission_type(msg.mission_type)
        if mission_type is None:
            return [self._ack(peer, MissionResult.UNSUPPORTED, msg.mission_type)]
        count = MissionCount(
            count=len(self._stores[mission_type]),
            mission_type=mission_type,
            opaque_id=self._opaque[mission_type],
        )
        return [Send(peer, count)]

    def _on_request(self, peer: Peer, msg: MissionRequest) -> list[Output]:
        mission_type = self._mission_type(msg.mission_type)
        if mission_type is None:
            return [self._ack(peer, MissionResult.UNSUPPORTED, msg.mission_type)]
        items = self._stores[mission_type]
        if not 0 <= msg.seq < len(items):
            return [self._ack(peer, MissionResult.INVALID_SEQUENCE, mission_type)]
        item = MissionItemMessage(
            seq=msg.seq,
            item=items[msg.seq],
            mission_type=mission_type,
            int_form=msg.int_form,
        )
        return [Send(peer, item)]

    def _on_clear(self, peer: Peer, msg: MissionClearAll) -> list[Output]:
        if msg.mission_type == MISSION_TYPE_ALL:
            types = list(MissionType)
        else:
            mission_type = self._mission_type(msg.mission_type)
            if mission_type is None:
                return [self._ack(peer, MissionResult.UNSUPPORTED, msg.mission_type)]
            types = [mission_type]
        if self._upload is not None and self._upload.peer != peer:
            return [self._ack(peer, MissionResult.DENIED, msg.mission_type)]
        self._upload = None
        out: list[Output] = [self._ack(peer, MissionResult.ACCEPTED, msg.mission_type)]
        for mission_type in types:
            self._stores[mission_type] = ()
            self._opaque[mission_type] = opaque_id_of(())
            out.append(Replaced(mission_type, ()))
        return out

    def _on_ack(self, peer: Peer, msg: MissionAck) -> list[Output]:
        up = self._upload
        if up is not None and up.peer == peer and msg.mission_type == up.mission_type:
            # The uploader gave up (OPERATION_CANCELLED or an error): keep the old list.
            self._upload = None
            return [Failed(up.mission_type, MissionResult.OPERATION_CANCELLED,
                           f"cancelled by the ground station (result {msg.result})")]  # fmt: skip
        return []  # the end of a download: nothing to do


def _wire_key(items: Sequence[MissionItem]) -> bytes:
    """The list as MISSION_ITEM_INT carries it (float32 params, degE7 positions): a plan read
    from a file and the same plan uploaded compare equal, as PX4's mission id does."""
    out = bytearray()
    for item in items:
        lat, lon = (round(v * 1e7) if math.isfinite(v) else 0 for v in (item.lat_deg, item.lon_deg))
        out += struct.pack(
            "<HBB4fqqf",
            item.command & 0xFFFF,
            item.frame & 0xFF,
            int(item.autocontinue),
            *item.params[:4],
            lat,
            lon,
            item.alt_m,
        )
    return bytes(out)


def same_items(a: Sequence[MissionItem], b: Sequence[MissionItem]) -> bool:
    """Item lists equal field by field, NaN equal to NaN (for round-trip checks)."""
    if len(a) != len(b):
        return False
    for x, y in zip(a, b, strict=True):
        for name in MissionItem.__slots__:
            u, v = getattr(x, name), getattr(y, name)
            if u != v and not (
                isinstance(u, float) and isinstance(v, float) and math.isnan(u) and math.isnan(v)
            ):
                return False
    return True
