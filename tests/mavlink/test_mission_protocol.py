"""The sans-IO mission protocol: result codes, atomic replacement, timeouts, lossy links."""

from __future__ import annotations

import math
from collections.abc import Sequence

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from air_sitl.mavlink import messages
from air_sitl.mavlink.codec import (
    Encoder,
    ParseCounters,
    Parser,
    from_mission_message,
    to_mission_message,
)
from air_sitl.mavlink.mission_protocol import (
    ITEM_TIMEOUT_NS,
    MAX_RETRIES,
    Failed,
    MissionProtocol,
    Output,
    Replaced,
    Send,
    same_items,
)
from air_sitl.mission.items import MavCmd, MavFrame, MissionItem, MissionResult, MissionType

GCS = messages.Peer(255, 190)
OTHER = messages.Peer(254, 1)
MS = 1_000_000


def wp(lat: float, lon: float = 8.5, alt: float = 100.0) -> MissionItem:
    return MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=lat, lon_deg=lon, alt_m=alt)


OLD = (wp(47.0), wp(47.001), MissionItem(command=MavCmd.NAV_RETURN_TO_LAUNCH, frame=2))
NEW = tuple(wp(47.0 + i * 1e-3, 8.5 + i * 1e-3, 100.0 + i) for i in range(6))


def sends(out: Sequence[Output]) -> list[messages.MissionMessage]:
    return [o.message for o in out if isinstance(o, Send)]


def ack_of(out: Sequence[Output]) -> messages.MissionAck:
    acks = [m for m in sends(out) if isinstance(m, messages.MissionAck)]
    assert len(acks) == 1, out
    return acks[0]


def upload(
    proto: MissionProtocol,
    items: Sequence[MissionItem],
    mission_type: int = MissionType.MISSION,
    peer: messages.Peer = GCS,
    int_form: bool = True,
) -> list[Output]:
    """Answer every request in order; return every output of the transfer."""
    outputs = proto.handle(
        peer, messages.MissionCount(count=len(items), mission_type=mission_type), 0
    )
    all_out = list(outputs)
    while True:
        reqs = [m for m in sends(outputs) if isinstance(m, messages.MissionRequest)]
        if not reqs:
            return all_out
        seq = reqs[-1].seq
        # The vehicle asks for MISSION_ITEM_INT first, then in the form the client answers in.
        assert reqs[-1].int_form is (int_form or seq == 0)
        msg = messages.MissionItemMessage(
            seq=seq, item=items[seq], mission_type=mission_type, int_form=int_form
        )
        outputs = proto.handle(peer, msg, 0)
        all_out += outputs


def test_upload_then_download_returns_the_same_items() -> None:
    proto = MissionProtocol(mission=OLD)
    out = upload(proto, NEW)
    assert ack_of(out).result == MissionResult.ACCEPTED
    assert [o for o in out if isinstance(o, Replaced)] == [Replaced(MissionType.MISSION, NEW)]
    count = sends(proto.handle(GCS, messages.MissionRequestList(), 0))
    assert count == [
        messages.MissionCount(
            count=len(NEW), mission_type=0, opaque_id=proto.opaque_id(MissionType.MISSION)
        )
    ]
    got = []
    for seq in range(len(NEW)):
        (item,) = sends(proto.handle(GCS, messages.MissionRequest(seq=seq), 0))
        assert isinstance(item, messages.MissionItemMessage) and item.seq == seq
        got.append(item.item)
    assert same_items(got, NEW)
    assert proto.opaque_id(MissionType.MISSION) != MissionProtocol(mission=OLD).opaque_id(0)


def test_old_float_messages_are_accepted_and_answered_in_kind() -> None:
    proto = MissionProtocol()
    out = upload(proto, NEW, int_form=False)
    assert ack_of(out).result == MissionResult.ACCEPTED
    (item,) = sends(proto.handle(GCS, messages.MissionRequest(seq=1, int_form=False), 0))
    assert isinstance(item, messages.MissionItemMessage) and not item.int_form


def bad(**changes: float) -> MissionItem:
    fields = {"command": MavCmd.NAV_WAYPOINT, "lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 50.0}
    fields.update(changes)
    return MissionItem(**fields)  # type: ignore[arg-type]


BAD_ITEMS = [
    (bad(lat_deg=91.0), MissionResult.INVALID_PARAM5_X),
    (bad(lat_deg=math.nan), MissionResult.INVALID_PARAM5_X),
    (bad(lon_deg=-181.0), MissionResult.INVALID_PARAM6_Y),
    (bad(alt_m=math.nan), MissionResult.INVALID_PARAM7),
    (bad(command=MavCmd.NAV_LOITER_TURNS, param1=math.nan), MissionResult.INVALID_PARAM1),
    (bad(command=9999), MissionResult.UNSUPPORTED),
    (bad(frame=99), MissionResult.UNSUPPORTED_FRAME),
    (bad(frame=MavFrame.GLOBAL_TERRAIN_ALT), MissionResult.UNSUPPORTED_FRAME),
    (bad(param1=math.inf), MissionResult.INVALID_PARAM1),
]


def test_bad_items_get_their_result_code_and_keep_the_old_mission() -> None:
    for item, expected in BAD_ITEMS:
        proto = MissionProtocol(mission=OLD)
        out = upload(proto, (wp(47.0), item, wp(47.002)))
        assert ack_of(out).result == expected, item
        assert not any(isinstance(o, Replaced) for o in out)
        assert any(isinstance(o, Failed) and o.result == expected for o in out)
        assert proto.items(MissionType.MISSION) == OLD
        assert not proto.busy


def test_jump_to_nowhere_is_invalid_sequence() -> None:
    proto = MissionProtocol(mission=OLD)
    jump = MissionItem(command=MavCmd.DO_JUMP, frame=2, param1=7, param2=1)
    out = upload(proto, (wp(47.0), wp(47.001), jump))
    assert ack_of(out).result == MissionResult.INVALID_SEQUENCE
    assert proto.items(MissionType.MISSION) == OLD


def test_count_zero_clears_and_count_65535_is_no_space() -> None:
    proto = MissionProtocol(mission=OLD)
    out = proto.handle(GCS, messages.MissionCount(count=65535), 0)
    assert ack_of(out).result == MissionResult.NO_SPACE
    assert proto.items(MissionType.MISSION) == OLD
    out = proto.handle(GCS, messages.MissionCount(count=0), 0)
    assert ack_of(out).result == MissionResult.ACCEPTED
    assert proto.items(MissionType.MISSION) == ()


def test_unknown_mission_type_is_unsupported() -> None:
    proto = MissionProtocol(mission=OLD)
    assert ack_of(proto.handle(GCS, messages.MissionCount(count=2, mission_type=7), 0)).result == (
        MissionResult.UNSUPPORTED
    )


def test_second_uploader_is_denied_and_the_first_completes() -> None:
    proto = MissionProtocol(mission=OLD)
    first = proto.handle(GCS, messages.MissionCount(count=2), 0)
    assert sends(first) == [messages.MissionRequest(seq=0)]
    denied = proto.handle(OTHER, messages.MissionCount(count=1), 0)
    assert [o.peer for o in denied if isinstance(o, Send)] == [OTHER]
    assert ack_of(denied).result == MissionResult.DENIED
    assert ack_of(proto.handle(OTHER, messages.MissionClearAll(), 0)).result == MissionResult.DENIED
    assert proto.handle(OTHER, messages.MissionItemMessage(seq=0, item=wp(1.0)), 0) == []
    proto.handle(GCS, messages.MissionItemMessage(seq=0, item=NEW[0]), 0)
    out = proto.handle(GCS, messages.MissionItemMessage(seq=1, item=NEW[1]), 0)
    assert ack_of(out).result == MissionResult.ACCEPTED
    assert proto.items(MissionType.MISSION) == NEW[:2]


def test_item_requests_are_retried_then_the_upload_is_cancelled() -> None:
    proto = MissionProtocol(mission=OLD)
    proto.handle(GCS, messages.MissionCount(count=3), 0)
    assert proto.tick(ITEM_TIMEOUT_NS - 1) == []
    retries = 0
    t = 0
    while True:
        t += ITEM_TIMEOUT_NS
        out = proto.tick(t)
        if any(isinstance(m, messages.MissionAck) for m in sends(out)):
            break
        assert sends(out) == [messages.MissionRequest(seq=0)]
        retries += 1
    assert retries == MAX_RETRIES
    assert ack_of(out).result == MissionResult.OPERATION_CANCELLED
    assert proto.items(MissionType.MISSION) == OLD and not proto.busy


def test_out_of_range_and_duplicate_items() -> None:
    proto = MissionProtocol(mission=OLD)
    proto.handle(GCS, messages.MissionCount(count=3), 0)
    proto.handle(GCS, messages.MissionItemMessage(seq=0, item=NEW[0]), 0)
    assert proto.handle(GCS, messages.MissionItemMessage(seq=0, item=NEW[0]), 0) == []  # duplicate
    ahead = proto.handle(GCS, messages.MissionItemMessage(seq=2, item=NEW[2]), 0)
    assert sends(ahead) == [messages.MissionRequest(seq=1)]  # out of order: ask for ours again
    out = proto.handle(GCS, messages.MissionItemMessage(seq=3, item=NEW[3]), 0)
    assert ack_of(out).result == MissionResult.INVALID_SEQUENCE
    assert proto.items(MissionType.MISSION) == OLD


def test_lost_final_ack_is_sent_again() -> None:
    proto = MissionProtocol()
    out = upload(proto, NEW)
    again = proto.handle(GCS, messages.MissionItemMessage(seq=len(NEW) - 1, item=NEW[-1]), 0)
    assert sends(again) == [ack_of(out)]


def test_gcs_cancel_keeps_the_old_list() -> None:
    proto = MissionProtocol(mission=OLD)
    proto.handle(GCS, messages.MissionCount(count=3), 0)
    proto.handle(GCS, messages.MissionItemMessage(seq=0, item=NEW[0]), 0)
    out = proto.handle(GCS, messages.MissionAck(result=MissionResult.OPERATION_CANCELLED), 0)
    assert [type(o) for o in out] == [Failed]
    assert proto.items(MissionType.MISSION) == OLD and not proto.busy


def test_mission_fence_and_rally_are_stored_separately() -> None:
    proto = MissionProtocol(mission=OLD)
    fence = tuple(
        MissionItem(
            command=MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION, param1=4, lat_deg=la, lon_deg=lo
        )
        for la, lo in ((47.0, 8.0), (47.0, 8.1), (47.1, 8.1), (47.1, 8.0))
    )
    rally = (MissionItem(command=MavCmd.NAV_RALLY_POINT, lat_deg=47.05, lon_deg=8.05, alt_m=50),)
    assert ack_of(upload(proto, fence, MissionType.FENCE)).result == MissionResult.ACCEPTED
    assert ack_of(upload(proto, rally, MissionType.RALLY)).result == MissionResult.ACCEPTED
    # A waypoint is not a fence item, a fence vertex not a mission item.
    assert ack_of(upload(proto, NEW, MissionType.FENCE)).result == MissionResult.UNSUPPORTED
    assert ack_of(upload(proto, fence, MissionType.MISSION)).result == MissionResult.UNSUPPORTED
    assert proto.items(MissionType.MISSION) == OLD
    assert proto.items(MissionType.FENCE) == fence
    assert proto.items(MissionType.RALLY) == rally
    out = proto.handle(GCS, messages.MissionClearAll(mission_type=MissionType.FENCE), 0)
    assert ack_of(out).result == MissionResult.ACCEPTED
    assert proto.items(MissionType.FENCE) == () and proto.items(MissionType.RALLY) == rally
    proto.handle(GCS, messages.MissionClearAll(mission_type=messages.MISSION_TYPE_ALL), 0)
    assert all(proto.items(t) == () for t in MissionType)


# --- a lossy link, through real MAVLink bytes ------------------------------------------------


class LossyLink:
    """Encodes each message with pymavlink, then drops, duplicates, delays or corrupts it."""

    def __init__(self, faults: list[int], sender: messages.Peer, receiver: messages.Peer) -> None:
        self.faults = faults
        self.encoder = Encoder(sender.system_id, sender.component_id)
        self.parser = Parser(ParseCounters())
        self.receiver = receiver
        self.in_flight: list[bytes] = []
        self.delayed: list[bytes] = []

    def send(self, message: messages.MissionMessage) -> None:
        frame = self.encoder.encode(
            from_mission_message(message, self.receiver.system_id, self.receiver.component_id)
        )
        fault = self.faults.pop(0) if self.faults else 0
        if fault == 1:  # drop
            return
        if fault == 2:  # duplicate
            self.in_flight += [frame, frame]
        elif fault == 3:  # reorder: overtaken by the next message
            self.delayed.append(frame)
            return
        elif fault == 4:  # corrupt one byte
            pos = len(self.faults) % len(frame)
            self.in_flight.append(frame[:pos] + bytes([frame[pos] ^ 0x5A]) + frame[pos + 1 :])
        else:
            self.in_flight.append(frame)
        self.in_flight += self.delayed
        self.delayed = []

    def receive(self) -> list[messages.MissionMessage]:
        frames, self.in_flight = self.in_flight, []
        out = []
        for frame in frames:
            for msg in self.parser.feed(frame, datagram=True):
                converted = to_mission_message(msg)
                if converted is not None:
                    out.append(converted)
        return out


class Uploader:
    """The ground-station side of an upload, with mavlink.io's timeouts and retries."""

    def __init__(self, items: Sequence[MissionItem], link: LossyLink) -> None:
        self.items = items
        self.link = link
        self.result: int | None = None
        self.gave_up = False
        self.last: messages.MissionMessage = messages.MissionCount(count=len(items))
        self.last_sent_ns = 0
        self.retries = 0
        link.send(self.last)

    @property
    def done(self) -> bool:
        return self.result is not None or self.gave_up

    def on_message(self, msg: messages.MissionMessage, now_ns: int) -> None:
        if self.done:
            return
        if isinstance(msg, messages.MissionAck):
            self.result = msg.result
        elif isinstance(msg, messages.MissionRequest) and 0 <= msg.seq < len(self.items):
            self.last = messages.MissionItemMessage(seq=msg.seq, item=self.items[msg.seq])
            self._send(now_ns)
            self.retries = 0

    def tick(self, now_ns: int) -> None:
        if self.done or now_ns - self.last_sent_ns < 1500 * MS:
            return
        if self.retries >= MAX_RETRIES:
            self.gave_up = True
            return
        self.retries += 1
        self._send(now_ns)

    def _send(self, now_ns: int) -> None:
        self.last_sent_ns = now_ns
        self.link.send(self.last)


waypoints = st.builds(
    wp,
    st.floats(-89.0, 89.0, allow_nan=False),
    st.floats(-179.0, 179.0, allow_nan=False),
    st.floats(-100.0, 3000.0, allow_nan=False, width=32),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    old=st.lists(waypoints, max_size=4),
    new=st.lists(waypoints, min_size=1, max_size=12),
    up_faults=st.lists(st.integers(0, 4), max_size=60),
    down_faults=st.lists(st.integers(0, 4), max_size=60),
)
def test_lossy_upload_is_all_or_nothing(
    old: list[MissionItem],
    new: list[MissionItem],
    up_faults: list[int],
    down_faults: list[int],
) -> None:
    """Dropped, duplicated, reordered, corrupted frames: exactly the new items, or the old."""
    vehicle = messages.Peer(1, 1)
    proto = MissionProtocol(mission=old)
    up = LossyLink(up_faults, GCS, vehicle)
    down = LossyLink(down_faults, vehicle, GCS)
    gcs = Uploader(new, up)
    now = 0
    for _ in range(3000):
        now += 10 * MS
        for msg in up.receive():
            for out in proto.handle(GCS, msg, now):
                if isinstance(out, Send):
                    down.send(out.message)
        for out in proto.tick(now):
            if isinstance(out, Send):
                down.send(out.message)
        for msg in down.receive():
            gcs.on_message(msg, now)
        gcs.tick(now)
        if gcs.done and not proto.busy and not up.in_flight and not up.delayed:
            break
    assert gcs.done
    stored = proto.items(MissionType.MISSION)
    # float32 altitude on the wire: compare with what MISSION_ITEM_INT can carry
    sent = [
        to_mission_message(from_mission_message(messages.MissionItemMessage(seq=i, item=it), 1, 1))
        for i, it in enumerate(new)
    ]
    sent_items = [m.item for m in sent if isinstance(m, messages.MissionItemMessage)]
    old_items = tuple(old)
    assert same_items(stored, sent_items) or stored == old_items, (
        f"stored {len(stored)} items: neither the {len(new)} sent nor the {len(old)} old"
    )
    if gcs.result == MissionResult.ACCEPTED:
        assert same_items(stored, sent_items)


def test_terrain_frames_are_accepted_only_with_a_terrain_model() -> None:
    items = (
        wp(47.0),
        bad(frame=MavFrame.GLOBAL_TERRAIN_ALT),
        bad(frame=MavFrame.GLOBAL_TERRAIN_ALT_INT, lat_deg=47.001),
    )
    assert ack_of(upload(MissionProtocol(), items)).result == MissionResult.UNSUPPORTED_FRAME
    proto = MissionProtocol(terrain=True)  # serve --dem
    assert ack_of(upload(proto, items)).result == MissionResult.ACCEPTED
    assert proto.items(MissionType.MISSION) == items
