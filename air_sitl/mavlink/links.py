"""Sockets of the MAVLink endpoint: ``udpout``, ``udpin`` and ``tcpin`` links, never blocking.

All sockets are non-blocking and served by one I/O thread through a selector. A TCP client
that stops reading gets its outgoing frames dropped once its buffer is full: a slow client can
never stall the endpoint, let alone the simulation.
"""

from __future__ import annotations

import contextlib
import ipaddress
import re
import selectors
import socket
import struct
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from air_sitl.errors import MavlinkError

Address = tuple[str, int]
UDP_MAX_PEERS = 32  # udpin/udpout peers kept (the least recently heard is dropped beyond)
TCP_MAX_BUFFER_BYTES = 256 * 1024  # per client; beyond this, frames to it are dropped
# The kernel's send buffer of a TCP client (autotuned, it grows to megabytes): enough for a
# second of full-rate telemetry over a slow link, small enough that a client that stops
# reading sees drops within seconds, not minutes of stale telemetry later.
TCP_SNDBUF_BYTES = 64 * 1024
# The kernel's receive buffer of a UDP link: room for a burst of thousands of small datagrams
# (5,000 PARAM_SET at once take ~5 MB of kernel memory) while the I/O thread catches up. The
# kernel caps it at net.core.rmem_max (4 MiB on most distributions, 208 kB on some).
UDP_RCVBUF_BYTES = 8 * 1024 * 1024
# Linux: SO_MEMINFO reads the socket's memory counters, the last of them (SK_MEMINFO_DROPS)
# the datagrams the kernel dropped for want of buffer, at any time (SO_RXQ_OVFL tells the same
# count, but only with the next datagram read: drops at the end of a burst would go unseen).
SO_MEMINFO = getattr(socket, "SO_MEMINFO", 55)
_MEMINFO = struct.Struct("=9I")  # SK_MEMINFO_VARS u32 counters; DROPS is the 9th
_URL = re.compile(r"^(udpout|udpin|tcpin)(?::|://)(\[[0-9a-fA-F:.]+\]|[^:\[\]]*):(\d{1,5})$")


@dataclass(frozen=True, slots=True)
class LinkSpec:
    """A parsed ``--mavlink`` URL."""

    kind: str  # "udpout", "udpin" or "tcpin"
    host: str
    port: int

    def __str__(self) -> str:
        return f"{self.kind}:{self.host}:{self.port}"

    @property
    def loopback(self) -> bool:
        """True when the link only talks to this machine."""
        if self.host == "localhost":
            return True
        try:
            return ipaddress.ip_address(self.host).is_loopback
        except ValueError:
            return False


def parse_link(text: str) -> LinkSpec:
    """``udpout:HOST:PORT``, ``udpin:HOST:PORT`` or ``tcpin:HOST:PORT`` (``://`` also accepted)."""
    m = _URL.match(text.strip())
    if m is None:
        msg = (
            f"--mavlink {text!r}: expected udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT "
            "(for example udpin:127.0.0.1:14550)"
        )
        raise MavlinkError(msg)
    kind, host, port = m.group(1), m.group(2).strip("[]"), int(m.group(3))
    if not host:
        msg = f"--mavlink {text!r}: give the address explicitly (127.0.0.1 for this machine only)"
        raise MavlinkError(msg)
    if not 0 <= port <= 65535 or (kind == "udpout" and port == 0):
        msg = f"--mavlink {text!r}: port {port} is not usable (expected 1..65535)"
        raise MavlinkError(msg)
    return LinkSpec(kind, host, port)


def _family(host: str) -> socket.AddressFamily:
    return socket.AF_INET6 if ":" in host else socket.AF_INET


@dataclass(slots=True, eq=False)
class Channel:
    """One peer of a link (a UDP address or a TCP connection): its parser state lives here."""

    link: Link
    address: Address
    parser: object  # codec.Parser, kept opaque so this module stays free of MAVLink
    last_seen_s: float = 0.0
    sock: socket.socket | None = None  # TCP only
    outbuf: bytearray = field(default_factory=bytearray)
    dropped_frames: int = 0


ReceiveFn = Callable[[Channel, bytes, bool], None]  # (channel, data, is_datagram)
NewParser = Callable[[], object]


class Link:
    """Base of the three link kinds: the peers, and the one socket each link binds."""

    _sock: socket.socket

    def __init__(self, spec: LinkSpec, encoder: object, receive: ReceiveFn, new_parser: NewParser):
        self.spec = spec
        self.encoder = encoder  # codec.Encoder of this link (its own sequence numbers)
        self.channels: dict[Address, Channel] = {}
        self._receive = receive
        self._new_parser = new_parser

    def register(self, sel: selectors.BaseSelector) -> None:
        """Add this link's sockets to the selector."""
        raise NotImplementedError

    def on_ready(self, sel: selectors.BaseSelector, key: selectors.SelectorKey, mask: int) -> None:
        """A registered socket is readable or writable."""
        raise NotImplementedError

    def send(self, data: bytes, channel: Channel | None = None) -> None:
        """Send to one channel, or to every current peer of the link."""
        raise NotImplementedError

    def close(self) -> None:
        """Close every socket."""
        raise NotImplementedError

    @property
    def local_address(self) -> Address:
        """Where the link's socket is bound (the real port when the URL said 0)."""
        host, port = self._sock.getsockname()[:2]
        return str(host), int(port)


def _size_for_bursts(sock: socket.socket) -> int | None:
    """Ask for a receive buffer of :data:`UDP_RCVBUF_BYTES`; the kernel's drop count so far
    (0) when it can be read (Linux, SO_MEMINFO), None when the platform does not give it."""
    with contextlib.suppress(OSError):
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, UDP_RCVBUF_BYTES)
    return _kernel_drop_count(sock) if sys.platform.startswith("linux") else None


def _kernel_drop_count(sock: socket.socket) -> int | None:
    """Datagrams the kernel dropped on ``sock`` so far (SK_MEMINFO_DROPS); None if unknown."""
    try:
        raw = sock.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, _MEMINFO.size)
        return int(_MEMINFO.unpack(raw)[8])
    except (OSError, struct.error):
        return None


class UdpLink(Link):
    """``udpout`` (send first to HOST:PORT, answer whoever replies) or ``udpin`` (bind)."""

    def __init__(self, spec: LinkSpec, encoder: object, receive: ReceiveFn, new_parser: NewParser):
        super().__init__(spec, encoder, receive, new_parser)
        self._sock = socket.socket(_family(spec.host), socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self.kernel_drops = _size_for_bursts(self._sock)  # None: the platform does not tell
        self._counters: Any = None  # the vehicle's ParseCounters (via the first parser)
        try:
            if spec.kind == "udpin":
                self._sock.bind((spec.host, spec.port))
                self._target: Address | None = None
            else:
                local = (
                    "127.0.0.1" if spec.loopback and _family(spec.host) is socket.AF_INET else ""
                )
                self._sock.bind((local, 0))
                self._target = (spec.host, spec.port)
                self._channel(self._target)
        except OSError as err:
            self._sock.close()
            msg = f"--mavlink {spec}: cannot open the UDP socket: {err.strerror}"
            raise MavlinkError(msg) from None

    def _channel(self, address: Address) -> Channel:
        ch = self.channels.get(address)
        if ch is None:
            if len(self.channels) >= UDP_MAX_PEERS:
                quiet = min(
                    (c for a, c in self.channels.items() if a != self._target),
                    key=lambda c: c.last_seen_s,
                )
                del self.channels[quiet.address]
            ch = Channel(self, address, self._new_parser(), time.monotonic())
            self.channels[address] = ch
            if self._counters is None:
                self._counters = getattr(ch.parser, "counters", None)
                if self._counters is not None and self.kernel_drops is not None:
                    self._counters.kernel_drops_counted = True
        return ch

    def register(self, sel: selectors.BaseSelector) -> None:
        """Watch the socket for datagrams."""
        sel.register(self._sock, selectors.EVENT_READ, self)

    def on_ready(self, sel: selectors.BaseSelector, key: selectors.SelectorKey, mask: int) -> None:
        """Read every waiting datagram."""
        for _ in range(256):  # bounded so one busy link cannot starve the others
            try:
                data, addr = self._sock.recvfrom(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # ICMP port unreachable from an absent udpout target
                continue
            address = (str(addr[0]), int(addr[1]))
            ch = self._channel(address)
            ch.last_seen_s = time.monotonic()
            self._receive(ch, data, True)
        self._count_kernel_drops()

    def _count_kernel_drops(self) -> None:
        """The kernel's running count of datagrams it dropped on this socket, added to the
        vehicle's counters as it grows (after each batch of reads, and at close)."""
        if self.kernel_drops is None:
            return
        total = _kernel_drop_count(self._sock)
        if total is None:
            return
        grown = total - self.kernel_drops
        if grown > 0 and self._counters is not None:
            self.kernel_drops = total
            self._counters.kernel_dropped += grown

    def send(self, data: bytes, channel: Channel | None = None) -> None:
        """Best effort: UDP drops what the kernel cannot take."""
        if channel is not None:
            self._sendto(data, channel.address)
            return
        for address in self.channels:
            self._sendto(data, address)

    def _sendto(self, data: bytes, address: Address) -> None:
        # A full buffer or an unreachable peer: telemetry is best effort.
        with contextlib.suppress(OSError):
            self._sock.sendto(data, address)

    def close(self) -> None:
        """Count the kernel's last drops, close the socket."""
        self._count_kernel_drops()
        self._sock.close()


class TcpServerLink(Link):
    """``tcpin``: accept any number of clients; each gets every frame while it keeps up."""

    def __init__(self, spec: LinkSpec, encoder: object, receive: ReceiveFn, new_parser: NewParser):
        super().__init__(spec, encoder, receive, new_parser)
        self._sel: selectors.BaseSelector | None = None
        self._sock = socket.socket(_family(spec.host), socket.SOCK_STREAM)
        self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._sock.setblocking(False)
        try:
            self._sock.bind((spec.host, spec.port))
            self._sock.listen(16)
        except OSError as err:
            self._sock.close()
            msg = f"--mavlink {spec}: cannot listen: {err.strerror}"
            raise MavlinkError(msg) from None

    def register(self, sel: selectors.BaseSelector) -> None:
        """Watch the listening socket."""
        self._sel = sel
        sel.register(self._sock, selectors.EVENT_READ, self)

    def on_ready(self, sel: selectors.BaseSelector, key: selectors.SelectorKey, mask: int) -> None:
        """Accept a client, read from one, or flush its buffer."""
        if key.fileobj is self._sock:
            self._accept(sel)
            return
        ch: Channel = key.data[1]
        if mask & selectors.EVENT_READ:
            self._read(sel, ch)
        if mask & selectors.EVENT_WRITE and ch.sock is not None:
            self._flush(sel, ch)

    def _accept(self, sel: selectors.BaseSelector) -> None:
        try:
            conn, addr = self._sock.accept()
        except (BlockingIOError, InterruptedError, OSError):
            return
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, TCP_SNDBUF_BYTES)
        address = (str(addr[0]), int(addr[1]))
        ch = Channel(self, address, self._new_parser(), time.monotonic(), sock=conn)
        self.channels[address] = ch
        sel.register(conn, selectors.EVENT_READ, (self, ch))

    def _read(self, sel: selectors.BaseSelector, ch: Channel) -> None:
        assert ch.sock is not None
        try:
            data = ch.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._drop(sel, ch)
            return
        ch.last_seen_s = time.monotonic()
        self._receive(ch, data, False)

    def _drop(self, sel: selectors.BaseSelector, ch: Channel) -> None:
        if ch.sock is not None:
            with contextlib.suppress(KeyError, ValueError):
                sel.unregister(ch.sock)
            ch.sock.close()
            ch.sock = None
        self.channels.pop(ch.address, None)

    def _flush(self, sel: selectors.BaseSelector, ch: Channel) -> None:
        assert ch.sock is not None
        try:
            sent = ch.sock.send(ch.outbuf)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:
            self._drop(sel, ch)
            return
        del ch.outbuf[:sent]
        events = selectors.EVENT_READ | (selectors.EVENT_WRITE if ch.outbuf else 0)
        with contextlib.suppress(KeyError, ValueError):
            sel.modify(ch.sock, events, (self, ch))

    def send(self, data: bytes, channel: Channel | None = None) -> None:
        """Queue ``data`` for one client or all; drop it for a client whose buffer is full."""
        targets = [channel] if channel is not None else list(self.channels.values())
        for ch in targets:
            if ch.sock is None:
                continue
            if len(ch.outbuf) + len(data) > TCP_MAX_BUFFER_BYTES:
                ch.dropped_frames += 1
                continue
            was_empty = not ch.outbuf
            ch.outbuf += data
            if was_empty and self._sel is not None:
                self._flush(self._sel, ch)

    def close(self) -> None:
        """Close the listening socket and every client."""
        for ch in list(self.channels.values()):
            if ch.sock is not None:
                ch.sock.close()
        self.channels.clear()
        self._sock.close()


def open_link(spec: LinkSpec, encoder: object, receive: ReceiveFn, new_parser: NewParser) -> Link:
    """Open the socket(s) of ``spec``."""
    if spec.kind == "tcpin":
        return TcpServerLink(spec, encoder, receive, new_parser)
    return UdpLink(spec, encoder, receive, new_parser)
