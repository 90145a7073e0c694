"""A ROS 2 peer written from rmw_zenoh's docs/design.md (and its attachment_helpers.cpp /
liveliness_utils.cpp where the document is silent), NOT from air_sitl's ROS 2 code.

It is what ``ros2 topic echo`` or an estimator node with ``RMW_IMPLEMENTATION=rmw_zenoh_cpp``
does on the wire: liveliness tokens ``@ros2_lv/<domain>/<zid>/<nid>/<id>/<kind>/<enclave>/
<namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`` ('/' inside a field written '%'), data on
``<domain>/<topic>/<pkg>::msg::dds_::<Type>_/<RIHS01 hash>``, an attachment serialized by
zenoh-ext (int64 sequence number, int64 source timestamp, 16-byte GID as a sequence), the GID
being XXH3-128 of the entity's token (low 64 bits, then high, little-endian), CDR payloads.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import xxhash
import zenoh
import zenoh.ext
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_KILTED)
CDR_LE_HEADER = b"\x00\x01\x00\x00"


def demangle(field_: str) -> str:
    return field_.replace("%", "/")


def dds_name(typename: str) -> str:
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def data_key(domain: int, topic: str, typename: str) -> str:
    return f"{domain}/{topic.strip('/')}/{dds_name(typename)}/{STORE.hash_rihs01(typename)}"


def gid(token: str) -> list[int]:
    digest = xxhash.xxh3_128_intdigest(token.encode())
    low, high = digest & (2**64 - 1), digest >> 64
    return list(low.to_bytes(8, "little") + high.to_bytes(8, "little"))


def attachment(seq: int, stamp_ns: int, gid_bytes: list[int]) -> bytes:
    value = (
        zenoh.ext.Int64(seq),
        zenoh.ext.Int64(stamp_ns),
        [zenoh.ext.UInt8(b) for b in gid_bytes],
    )
    return zenoh.ext.z_serialize(value).to_bytes()


def read_attachment(raw: bytes) -> tuple[int, int, list[int]]:
    seq, stamp, gid_bytes = zenoh.ext.z_deserialize(
        tuple[zenoh.ext.Int64, zenoh.ext.Int64, list[zenoh.ext.UInt8]], zenoh.ZBytes(raw)
    )
    return int(seq), int(stamp), [int(b) for b in gid_bytes]


@dataclass(frozen=True)
class Token:
    """One parsed liveliness token."""

    key: str
    domain: int
    zid: str
    nid: str
    id: str
    kind: str
    enclave: str
    namespace: str
    node: str
    topic: str | None = None
    type: str | None = None
    type_hash: str | None = None
    qos: str | None = None

    @classmethod
    def parse(cls, key: str) -> Token:
        p = key.split("/")
        assert p[0] == "@ros2_lv", key
        assert len(p) in (9, 13), key
        rest = {}
        if len(p) == 13:
            rest = {
                "topic": demangle(p[9]),
                "type": demangle(p[10]),
                "type_hash": p[11],
                "qos": p[12],
            }
        return cls(key, int(p[1]), p[2], p[3], p[4], p[5], demangle(p[6]), demangle(p[7]),
                   demangle(p[8]), **rest)  # fmt: skip


@dataclass
class Received:
    key: str
    payload: bytes
    attachment: bytes | None
    wall_ns: int


@dataclass
class RosPeer:
    """A zenoh peer session watching the ROS 2 graph of one domain and every data sample."""

    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    domain: int = 0
    tokens: list[Token] = field(default_factory=list)
    samples: list[Received] = field(default_factory=list)
    lock: threading.Lock = field(default_factory=threading.Lock)
    listeners: list[Callable[[Received], None]] = field(default_factory=list)

    def __post_init__(self) -> None:
        conf = zenoh.Config()
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("timestamping/enabled", "true")
        conf.insert_json5("listen/endpoints", repr(list(self.listen)).replace("'", '"'))
        conf.insert_json5("connect/endpoints", repr(list(self.connect)).replace("'", '"'))
        self.session = zenoh.open(conf)
        self._keep: list[Any] = []
        self._keep.append(
            self.session.liveliness().declare_subscriber(
                f"@ros2_lv/{self.domain}/**", self._on_token, history=True
            )
        )
        self._keep.append(self.session.declare_subscriber(f"{self.domain}/**", self._on_sample))
        self._next_id = 1

    def _on_token(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            with self.lock:
                self.tokens.append(Token.parse(str(sample.key_expr)))

    def _on_sample(self, sample: zenoh.Sample) -> None:
        att = sample.attachment
        got = Received(str(sample.key_expr), sample.payload.to_bytes(),
                       None if att is None else att.to_bytes(), time.time_ns())  # fmt: skip
        with self.lock:
            self.samples.append(got)
        for listener in self.listeners:
            listener(got)

    def received(self, key: str) -> list[Received]:
        with self.lock:
            return [s for s in self.samples if s.key == key]

    # -- being a node ---------------------------------------------------------------------
    def declare_node(self, name: str) -> None:
        zid = str(self.session.info.zid())
        self.zid, self.node = zid, name
        self._keep.append(
            self.session.liveliness().declare_token(
                f"@ros2_lv/{self.domain}/{zid}/0/0/NN/%/%/{name}"
            )
        )

    def declare_publisher(self, topic: str, typename: str) -> RosPublisher:
        token = (
            f"@ros2_lv/{self.domain}/{self.zid}/0/{self._next_id}/MP/%/%/{self.node}/"
            f"{topic.replace('/', '%')}/{dds_name(typename)}/{STORE.hash_rihs01(typename)}/"
            "::,10:,:,:,,"
        )
        self._next_id += 1
        self._keep.append(self.session.liveliness().declare_token(token))
        return RosPublisher(self.session, data_key(self.domain, topic, typename), gid(token))

    def close(self) -> None:
        for handle in self._keep:
            handle.undeclare()
        self.session.close()


class RosPublisher:
    def __init__(self, session: zenoh.Session, key: str, gid_bytes: list[int]) -> None:
        self.key = key
        self.gid = gid_bytes
        self.seq = 0
        self._pub = session.declare_publisher(key)

    def publish(self, payload: bytes, *, with_attachment: bool = True) -> None:
        self.seq += 1
        att = attachment(self.seq, time.time_ns(), self.gid) if with_attachment else None
        self._pub.put(payload, attachment=att)
