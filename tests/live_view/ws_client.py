"""A Foxglove WebSocket client written from the protocol's spec (not the SDK): RFC 6455
framing over a plain socket, subprotocol ``foxglove.sdk.v1``, JSON ``serverInfo`` /
``advertise`` / ``subscribe``, binary Message Data (opcode 1, subscription id u32, log time
u64, payload), each payload decoded with the schema its channel advertised."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import socket
import struct
from typing import Any

from .decode import Decoder

SUBPROTOCOL = "foxglove.sdk.v1"
_GUID = "258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


class FoxgloveClient:
    """One connection; :meth:`recv` returns ("json", dict) or ("message", topic, t_ns, value)."""

    def __init__(self, host: str, port: int, timeout_s: float = 60.0) -> None:
        self.sock = socket.create_connection((host, port), timeout=timeout_s)
        key = base64.b64encode(os.urandom(16)).decode()
        request = (
            f"GET / HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
            f"Sec-WebSocket-Version: 13\r\nSec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n"
        )
        self.sock.sendall(request.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                raise ConnectionError("closed during the handshake")
            head += chunk
        lines = head.decode().split("\r\n")
        assert lines[0].split()[1] == "101", lines[0]
        headers = {
            k.lower(): v.strip() for k, _, v in (ln.partition(":") for ln in lines[1:] if ln)
        }
        accept = base64.b64encode(hashlib.sha1((key + _GUID).encode()).digest()).decode()
        assert headers["sec-websocket-accept"] == accept
        self.protocol = headers.get("sec-websocket-protocol")
        self.channels: dict[int, dict[str, Any]] = {}
        self.subscriptions: dict[int, int] = {}  # subscription id -> channel id
        self.decoder = Decoder()
        self.server_info: dict[str, Any] | None = None

    def _read(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("connection closed")
            out += chunk
        return out

    def _frame(self) -> tuple[int, bool, bytes]:
        b0, b1 = self._read(2)
        length = b1 & 0x7F
        if length == 126:
            length = struct.unpack(">H", self._read(2))[0]
        elif length == 127:
            length = struct.unpack(">Q", self._read(8))[0]
        mask = self._read(4) if b1 & 0x80 else None
        data = self._read(length)
        if mask is not None:
            data = bytes(c ^ mask[i % 4] for i, c in enumerate(data))
        return b0 & 0x0F, bool(b0 & 0x80), data

    def _send(self, opcode: int, data: bytes) -> None:
        mask = os.urandom(4)
        n = len(data)
        head = bytes([0x80 | opcode])
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 65536:
            head += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack(">Q", n)
        self.sock.sendall(head + mask + bytes(c ^ mask[i % 4] for i, c in enumerate(data)))

    def send_json(self, value: dict[str, Any]) -> None:
        self._send(0x1, json.dumps(value).encode())

    def _message(self) -> tuple[int, bytes]:
        opcode, fin, data = self._frame()
        while True:
            if opcode == 0x9:  # ping
                self._send(0xA, data)
            elif opcode == 0x8:
                raise ConnectionError("server closed the connection")
            elif opcode in (0x1, 0x2):
                while not fin:
                    _, fin, more = self._frame()
                    data += more
                return opcode, data
            opcode, fin, data = self._frame()

    def recv(self) -> tuple[Any, ...]:
        opcode, data = self._message()
        if opcode == 0x1:
            value = json.loads(data)
            if value.get("op") == "serverInfo":
                self.server_info = value
            elif value.get("op") == "advertise":
                for ch in value["channels"]:
                    self.channels[ch["id"]] = ch
                    if ch["encoding"] == "protobuf":
                        self.decoder.add(
                            ch["schemaName"], "protobuf", base64.b64decode(ch["schema"])
                        )
            return ("json", value)
        assert data[0] == 0x01, f"binary opcode {data[0]}"
        sub, t_ns = struct.unpack_from("<IQ", data, 1)
        ch = self.channels[self.subscriptions[sub]]
        value = self.decoder.decode(ch["schemaName"], ch["encoding"], data[13:])
        return ("message", ch["topic"], t_ns, value)

    def subscribe(self, topics: list[str]) -> None:
        subs = []
        for ch in self.channels.values():
            if ch["topic"] in topics:
                sid = len(self.subscriptions) + 1
                self.subscriptions[sid] = ch["id"]
                subs.append({"id": sid, "channelId": ch["id"]})
        self.send_json({"op": "subscribe", "subscriptions": subs})

    def next_message(self) -> tuple[str, int, Any]:
        """The next message (topic, log time, value); subscribes to every channel as it is
        advertised (the JSON operations in between are taken in)."""
        while True:
            item = self.recv()
            if item[0] == "message":
                return item[1], item[2], item[3]
            subscribed = set(self.subscriptions.values())
            new = [c["topic"] for i, c in self.channels.items() if i not in subscribed]
            if new:
                self.subscribe(new)

    def channels_by_topic(self, topic: str) -> dict[str, Any]:
        return next(c for c in self.channels.values() if c["topic"] == topic)

    def topics(self) -> set[str]:
        return {ch["topic"] for ch in self.channels.values()}

    def close(self) -> None:
        self.sock.close()
