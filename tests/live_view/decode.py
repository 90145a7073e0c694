"""Decoding Foxglove messages the way any client does: protobuf from the schema's
FileDescriptorSet (no SDK), JSON for JSON schemas."""

from __future__ import annotations

import json
from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory


class Decoder:
    """Decodes messages of the schemas it has been given (name, encoding, data)."""

    def __init__(self) -> None:
        self._classes: dict[str, Any] = {}

    def add(self, name: str, encoding: str, data: bytes) -> None:
        if encoding != "protobuf" or name in self._classes:
            return
        fds = descriptor_pb2.FileDescriptorSet.FromString(data)
        pool = descriptor_pool.DescriptorPool()
        for fd in fds.file:
            pool.Add(fd)
        self._classes[name] = message_factory.GetMessageClass(pool.FindMessageTypeByName(name))

    def decode(self, name: str, encoding: str, payload: bytes) -> Any:
        if encoding == "json":
            return json.loads(payload)
        return self._classes[name].FromString(payload)
