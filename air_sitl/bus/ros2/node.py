"""One ROS 2 node on a zenoh session, as rmw_zenoh announces and talks (see
:mod:`air_sitl.bus.ros2.layout`): its liveliness token, publishers that put CDR samples with
the attachment, and the tokens of its subscriptions."""

from __future__ import annotations

import time

from air_sitl.bus.ros2.layout import (
    Durability,
    Entity,
    Qos,
    encode_attachment,
    endpoint_token,
    gid_of,
    node_token,
    topic_key,
)
from air_sitl.bus.ros2.messages import Messages
from air_sitl.bus.ros2.options import Ros2Options
from air_sitl.bus.session import Bus, Publisher

CDR_ENCODING = "application/cdr"


class RosPublisher:
    """A ROS 2 publisher: its data key, its GID (from its token), its sequence number."""

    def __init__(self, publisher: Publisher, key: str, token: str) -> None:
        self._pub = publisher
        self.key = key
        self.token = token
        self.gid = gid_of(token)
        self.sequence_number = 0

    @property
    def matched(self) -> bool:
        """True when a subscriber listens to the data key."""
        return self._pub.matched

    def publish(self, payload: bytes) -> None:
        """Put one serialized message with its attachment (next sequence number, wall time)."""
        self.sequence_number += 1
        self._pub.put(payload, encode_attachment(self.sequence_number, time.time_ns(), self.gid))


class Ros2Node:
    """A node: its token is declared on creation; publishers and subscriptions get the next
    entity ids (the node's own id is 0, as the first node of an rmw_zenoh context)."""

    NODE_ID = 0

    def __init__(self, bus: Bus, options: Ros2Options, name: str, messages: Messages) -> None:
        self.bus = bus
        self.options = options
        self.name = name
        self.messages = messages
        self._zid = bus.zid
        self._next_id = self.NODE_ID + 1
        self.token = node_token(options.domain_id, self._zid, self.NODE_ID, options.namespace, name)
        bus.liveliness_token(self.token)

    def _entity(self, kind: Entity, topic: str, typename: str, qos: Qos) -> tuple[str, str]:
        """(data key, liveliness token) of a new publisher or subscription of ``topic``."""
        type_hash = self.messages.hash(typename)
        token = endpoint_token(
            kind,
            domain_id=self.options.domain_id,
            zid=self._zid,
            node_id=self.NODE_ID,
            entity_id=self._next_id,
            namespace=self.options.namespace,
            node=self.name,
            topic=topic,
            typename=typename,
            type_hash=type_hash,
            qos=qos,
        )
        self._next_id += 1
        return topic_key(self.options.domain_id, topic, typename, type_hash), token

    def publisher(
        self, topic: str, typename: str, qos: Qos | None = None, *, block: bool = False
    ) -> RosPublisher:
        """Declare a publisher of ``topic`` (fully qualified); transient-local ones keep their
        last ``depth`` samples for late subscribers."""
        qos = qos or Qos()
        key, token = self._entity(Entity.PUBLISHER, topic, typename, qos)
        if qos.durability is Durability.TRANSIENT_LOCAL:
            pub = self.bus.cached_publisher(key, encoding=CDR_ENCODING, depth=qos.depth)
        else:
            pub = self.bus.publisher(key, encoding=CDR_ENCODING, block=block, express=True)
        self.bus.liveliness_token(token)
        return RosPublisher(pub, key, token)

    def announce_subscription(self, topic: str, typename: str, qos: Qos | None = None) -> str:
        """Declare the token of a subscription of ``topic`` (so ``ros2 topic info`` counts it);
        its data key."""
        key, token = self._entity(Entity.SUBSCRIPTION, topic, typename, qos or Qos())
        self.bus.liveliness_token(token)
        return key
