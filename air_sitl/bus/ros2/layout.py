"""How rmw_zenoh lays ROS 2 out on zenoh: key expressions, liveliness tokens, GIDs, attachments.

Pure functions (no zenoh here), each from rmw_zenoh's ``docs/design.md`` and, where the
document is silent, its source (``rmw_zenoh_cpp/src/detail/``, rolling/kilted, zenoh 1.x):

- Topic key (``liveliness_utils.cpp``, ``TopicInfo``): ``<domain>/<topic without its leading
  and trailing '/'>/<pkg>::msg::dds_::<Type>_/<RIHS01 hash>``, the topic's '/' kept.
- Liveliness token (``liveliness_utils.cpp``, ``Entity``): ``@ros2_lv/<domain>/<zid>/<nid>/<id>/
  <NN|MP|MS|SS|SC>/<enclave>/<namespace>/<node>`` and, for a publisher or subscription,
  ``/<topic>/<type>/<hash>/<qos>``; every '/' inside a field written '%' (an empty namespace
  or enclave is ``%``); a node's token repeats its node id as entity id.
- QoS (``qos_to_keyexpr``): ``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:
  <lifespan s>,<ns>:<liveliness>,<lease s>,<ns>``, each field empty when it equals rmw_zenoh's
  default (reliable, volatile, keep last, depth 42, infinite durations, automatic; ``qos.cpp``).
- GID (``Entity`` constructor): XXH3-128 of the whole liveliness token, low 64 bits then high
  64 bits, each little-endian.
- Attachment (``attachment_helpers.cpp``, ``AttachmentData::serialize_to_zbytes``, zenoh-ext
  serializer): int64 sequence number, int64 source timestamp (ns since the epoch), then the GID
  as a sequence: a LEB128 length (16) and 16 bytes; 33 bytes in all, integers little-endian.
  (Jazzy releases before 0.2.4 wrote string keys before each field; that layout is not read.)
- Payload (``type_support.cpp``): CDR with its 4-byte encapsulation header (rosbags writes it).
"""

from __future__ import annotations

import re
import struct
from dataclasses import dataclass
from enum import Enum

import xxhash

from air_sitl.errors import OptionError

ADMIN_SPACE = "@ros2_lv"
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE
_ATTACHMENT = struct.Struct(f"<qqB{GID_SIZE}s")

# A ROS 2 name token: letters, digits, '_', not starting with a digit (rcl's validation).
_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


class Entity(Enum):
    """The two-letter kinds of rmw_zenoh's liveliness tokens."""

    NODE = "NN"
    PUBLISHER = "MP"
    SUBSCRIPTION = "MS"


class Reliability(Enum):
    """rmw_qos_reliability_policy_e values."""

    RELIABLE = 1
    BEST_EFFORT = 2


class Durability(Enum):
    """rmw_qos_durability_policy_e values."""

    TRANSIENT_LOCAL = 1
    VOLATILE = 2


DEFAULT_DEPTH = 42  # rmw_zenoh's default history depth


@dataclass(frozen=True, slots=True)
class Qos:
    """The QoS a publisher or subscription announces (keep-last history, no deadlines)."""

    reliability: Reliability = Reliability.RELIABLE
    durability: Durability = Durability.VOLATILE
    depth: int = 10

    def keyexpr(self) -> str:
        """The token's QoS field, each value empty when it is rmw_zenoh's default."""
        rel = "" if self.reliability is Reliability.RELIABLE else str(self.reliability.value)
        dur = "" if self.durability is Durability.VOLATILE else str(self.durability.value)
        depth = "" if self.depth == DEFAULT_DEPTH else str(self.depth)
        return f"{rel}:{dur}:,{depth}:,:,:,,"


def ros_name_token(what: str, value: str) -> str:
    """Validate one token of a ROS 2 name (node name, topic part)."""
    if not _TOKEN.fullmatch(value):
        msg = (
            f"{what}: {value!r} is not a ROS 2 name (letters, digits and '_', not starting "
            "with a digit)"
        )
        raise OptionError(msg)
    return value


def mangle(name: str) -> str:
    """A name as one key chunk: every '/' written '%' (so '/' alone becomes '%')."""
    return name.replace("/", "%")


def dds_type_name(typename: str) -> str:
    """``pkg/msg/Type`` -> ``pkg::msg::dds_::Type_`` (the type name rmw_zenoh keys carry)."""
    pkg, kind, name = typename.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def topic_key(domain_id: int, topic: str, typename: str, type_hash: str) -> str:
    """The data key of a topic (its fully qualified name, e.g. ``/air/uav0/imu``)."""
    return f"{domain_id}/{topic.strip('/')}/{dds_type_name(typename)}/{type_hash}"


def node_token(domain_id: int, zid: str, node_id: int, namespace: str, node: str) -> str:
    """Liveliness token of a node (enclave '/')."""
    return (
        f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{node_id}/{Entity.NODE.value}/%/"
        f"{mangle(namespace)}/{mangle(node)}"
    )


def endpoint_token(
    kind: Entity,
    *,
    domain_id: int,
    zid: str,
    node_id: int,
    entity_id: int,
    namespace: str,
    node: str,
    topic: str,
    typename: str,
    type_hash: str,
    qos: Qos,
) -> str:
    """Liveliness token of a publisher (MP) or subscription (MS) of ``topic``."""
    return (
        f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{entity_id}/{kind.value}/%/"
        f"{mangle(namespace)}/{mangle(node)}/{mangle(topic)}/{mangle(dds_type_name(typename))}/"
        f"{type_hash}/{qos.keyexpr()}"
    )


def gid_of(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh derives from an entity's liveliness token."""
    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_SIZE, "little")


def encode_attachment(sequence_number: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    """The attachment of every sample (see the module docstring)."""
    return _ATTACHMENT.pack(sequence_number, source_timestamp_ns, GID_SIZE, gid)


def decode_attachment(attachment: bytes | None) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID); ValueError when it is not one."""
    if attachment is None:
        msg = "no attachment"
        raise ValueError(msg)
    if len(attachment) != ATTACHMENT_SIZE:
        msg = f"attachment of {len(attachment)} bytes, expected {ATTACHMENT_SIZE}"
        raise ValueError(msg)
    seq, stamp, size, gid = _ATTACHMENT.unpack(attachment)
    if size != GID_SIZE:
        msg = f"attachment GID of {size} bytes, expected {GID_SIZE}"
        raise ValueError(msg)
    return seq, stamp, gid
