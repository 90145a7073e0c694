"""The zenoh adapter: the only module of air-sitl that imports ``zenoh``.

:func:`open_bus` returns a :class:`Bus` (a context manager) with the few operations air-sitl
needs: publishers (drop-on-congestion by default), callback subscribers, queryables and
queries. Everything above it deals in ``bytes`` and plain callables, so it can be read (and
swapped) without knowing zenoh.

Defaults: peer mode, multicast scouting off, endpoints on ``tcp/127.0.0.1`` only. With
``config_file`` (zenoh JSON5: TLS, access control, ...) the file is the base and only the
options given explicitly (mode, listen, connect) are applied on top of it.

Peers through a router: since zenoh 1.9 a router no longer forwards between two peers attached
to it (``routing.router.peers_failover_brokering`` is gone; the router's default gateway puts
every peer in one peer-to-peer region, assumed fully meshed). It only tells each peer where the
others listen (gossip), and the peers connect to one another. A peer that listens nowhere can
be told of by no one: two such peers hear nothing of each other. So a peer that connects and
was given no listen endpoint listens on an ephemeral TCP port of the address it reaches its
connect endpoints from (the loopback for a loopback router): :func:`peer_listen_endpoints`.
Clients need nothing of the sort: the router forwards for them.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import re
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import zenoh
import zenoh.ext

from air_sitl.bus.defaults import DEFAULT_ENDPOINT
from air_sitl.closeable import Closeable
from air_sitl.errors import BusError

TX_QUEUE_BATCHES = 16  # zenoh's default is 2 batches of 64 kB per priority

Mode = Literal["peer", "client", "router"]


@dataclass(frozen=True, slots=True, kw_only=True)
class BusConfig:
    """How to join the bus.

    ``listen``/``connect`` None means "the default": a simulator (``serves=True``) listens on
    :data:`DEFAULT_ENDPOINT`, any other program connects to it. Empty tuples mean none.
    """

    mode: Mode = "peer"
    listen: tuple[str, ...] | None = None
    connect: tuple[str, ...] | None = None
    config_file: Path | None = None
    serves: bool = False  # True for the simulator and the router: listen by default
    timestamping: bool = False  # stamp every sample (cached publishers need it; ROS 2 view)


@dataclass(frozen=True, slots=True)
class Message:
    """One received sample: key, payload, optional attachment, all plain bytes."""

    key: str
    payload: bytes
    attachment: bytes | None


def zenoh_config(cfg: BusConfig) -> zenoh.Config:
    """Build the zenoh Config for ``cfg`` (BusError naming the file on a bad config)."""
    if cfg.config_file is not None:
        try:
            conf = zenoh.Config.from_file(str(cfg.config_file))
        except (zenoh.ZError, OSError, ValueError) as err:
            msg = f"{cfg.config_file}: not a usable zenoh JSON5 config: {_one_line(err)}"
            raise BusError(msg) from None
        listen, connect = cfg.listen, cfg.connect
        mode: str | None = cfg.mode if cfg.mode != "peer" else None
    else:
        conf = zenoh.Config()
        _insert(conf, "scouting/multicast/enabled", False)
        # Room for bursts of frames (the camera threads deliver several at once): a slow
        # reader still loses samples (drop on congestion), a merely busy one does not.
        _insert(conf, "transport/link/tx/queue/size/data", TX_QUEUE_BATCHES)
        # A program started before the simulator connects within a second of it coming up.
        _insert(conf, "connect/retry", {"period_init_ms": 100, "period_max_ms": 1000})
        listen, connect = cfg.listen, cfg.connect
        if listen is None and connect is None:
            listen, connect = ((DEFAULT_ENDPOINT,), ()) if cfg.serves else ((), (DEFAULT_ENDPOINT,))
        listen = listen or ()
        connect = connect or ()
        mode = cfg.mode
        if mode == "peer" and not listen and connect:
            listen = peer_listen_endpoints(connect)
    if cfg.timestamping:
        _insert(conf, "timestamping/enabled", True)
    if mode is not None:
        _insert(conf, "mode", mode)
    if listen is not None:
        _insert(conf, "listen/endpoints", list(listen))
    if connect is not None:
        _insert(conf, "connect/endpoints", list(connect))
    return conf


def peer_listen_endpoints(connect: tuple[str, ...]) -> tuple[str, ...]:
    """Ephemeral TCP endpoints a connecting peer listens on, so other peers can reach it.

    One per local address the TCP connect endpoints are reached from: ``tcp/127.0.0.1:0`` for
    a loopback router, ``tcp/<this host's address on that network>:0`` for a router on
    another host or container (never the wildcard address). An endpoint whose host does not
    resolve, or of another protocol, adds none.
    """
    out: list[str] = []
    for endpoint in connect:
        local = _local_address_towards(endpoint)
        if local is None:
            continue
        text = f"tcp/[{local}]:0" if ":" in local else f"tcp/{local}:0"
        if text not in out:
            out.append(text)
    return tuple(out)


_TCP_ENDPOINT = re.compile(r"tcp/(?:\[(?P<v6>[^\]]+)\]|(?P<host>[^:/#?]+)):(?P<port>\d+)")


def _local_address_towards(endpoint: str) -> str | None:
    """The local IP address packets to ``endpoint`` leave from (no packet is sent)."""
    m = _TCP_ENDPOINT.match(endpoint)
    if m is None:
        return None
    host = m.group("v6") or m.group("host")
    try:
        if ipaddress.ip_address(host).is_loopback:
            return str(host)
    except ValueError:
        if host == "localhost":
            return "127.0.0.1"
    try:
        infos = socket.getaddrinfo(host, int(m.group("port")), type=socket.SOCK_DGRAM)
    except (OSError, UnicodeError):
        return None
    for family, kind, proto, _, address in infos:
        with socket.socket(family, kind, proto) as probe:
            try:
                probe.connect(address)  # UDP: only picks the route and the source address
            except OSError:
                continue
            return str(probe.getsockname()[0])
    return None


def _insert(conf: zenoh.Config, key: str, value: Any) -> None:
    try:
        conf.insert_json5(key, json.dumps(value))
    except (zenoh.ZError, ValueError) as err:
        msg = f"zenoh config {key} = {value!r}: {_one_line(err)}"
        raise BusError(msg) from None


def _one_line(err: BaseException) -> str:
    """The first line of a zenoh error, without its Rust source locations."""
    lines = str(err).strip().splitlines()
    text = lines[0] if lines else type(err).__name__
    return re.sub(r"\s+at \S+\.rs:\d+\.?", "", text).strip()


class Publisher:
    """A declared publisher on one key; ``put`` never blocks unless ``reliable_block``."""

    def __init__(self, pub: zenoh.Publisher) -> None:
        self._pub = pub

    def put(self, payload: bytes, attachment: bytes | None = None) -> None:
        """Send one sample (dropped under congestion unless declared blocking)."""
        self._pub.put(payload, attachment=attachment)

    @property
    def matched(self) -> bool:
        """True when at least one subscriber matches this key."""
        # zenoh-python 1.x returns a MatchingStatus object (its stub says bool): read .matching.
        status: Any = self._pub.matching_status
        return bool(getattr(status, "matching", status))

    def close(self) -> None:
        """Undeclare."""
        self._pub.undeclare()  # type: ignore[no-untyped-call]


@dataclass(frozen=True, slots=True)
class QueryRequest:
    """What a queryable handler receives."""

    key: str
    parameters: str
    payload: bytes
    attachment: bytes | None


@dataclass(frozen=True, slots=True)
class QueryAnswer:
    """What a queryable handler returns."""

    payload: bytes
    attachment: bytes | None = None
    encoding: str | None = None


class Bus(Closeable):
    """An open zenoh session with air-sitl's small vocabulary; close it (or use ``with``)."""

    def __init__(self, session: zenoh.Session, cfg: BusConfig) -> None:
        self._session = session
        self.config = cfg
        self._handles: list[Any] = []
        self._lock = threading.Lock()
        self._closed = False
        self.callback_errors: list[str] = []  # exceptions raised inside our callbacks

    @property
    def zid(self) -> str:
        """This session's zenoh id."""
        return str(self._session.info.zid())

    def peers(self) -> list[str]:
        """Zenoh ids of connected peers and routers."""
        info = self._session.info
        return [str(z) for z in (*info.peers_zid(), *info.routers_zid())]

    def publisher(
        self, key: str, *, encoding: str, block: bool = False, express: bool = False
    ) -> Publisher:
        """Declare a publisher; ``block=False`` drops samples under congestion (never waits)."""
        cc = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
        pub = self._session.declare_publisher(
            key, encoding=encoding, congestion_control=cc, express=express
        )
        return Publisher(pub)

    def cached_publisher(self, key: str, *, encoding: str, depth: int) -> Publisher:
        """A publisher whose last ``depth`` samples late subscribers can ask for (zenoh-ext's
        advanced publisher, detectable: a ROS 2 transient-local publisher). Needs a session
        opened with ``timestamping``."""
        pub = zenoh.ext.declare_advanced_publisher(
            self._session,
            key,
            encoding=encoding,
            cache=zenoh.ext.CacheConfig(max_samples=depth),
            publisher_detection=True,
        )
        return Publisher(pub)  # type: ignore[arg-type]

    def liveliness_token(self, key: str) -> None:
        """Declare a liveliness token on ``key`` until the session closes."""
        token = self._session.liveliness().declare_token(key)
        with self._lock:
            self._handles.append(token)

    def subscribe(self, key: str, callback: Callable[[Message], None]) -> None:
        """Call ``callback`` (on a zenoh thread) for every sample on ``key`` until closed."""

        def on_sample(sample: zenoh.Sample) -> None:
            att = sample.attachment
            message = Message(
                str(sample.key_expr),
                sample.payload.to_bytes(),
                None if att is None else att.to_bytes(),
            )
            self._guard(callback, message)

        sub = self._session.declare_subscriber(key, zenoh.handlers.Callback(on_sample))
        with self._lock:
            self._handles.append(sub)

    def queryable(self, key: str, handler: Callable[[QueryRequest], QueryAnswer]) -> None:
        """Answer queries on ``key``; a BusError from ``handler`` becomes an error reply."""

        def on_query(query: zenoh.Query) -> None:
            payload = query.payload
            att = query.attachment
            request = QueryRequest(
                str(query.key_expr),
                str(query.parameters),
                b"" if payload is None else payload.to_bytes(),
                None if att is None else att.to_bytes(),
            )
            try:
                answer = handler(request)
            except BusError as err:
                query.reply_err(str(err).encode())
                return
            except Exception as err:
                query.reply_err(f"{type(err).__name__}: {err}".encode())
                raise
            query.reply(
                query.key_expr,
                answer.payload,
                attachment=answer.attachment,
                encoding=answer.encoding,
            )

        def guarded(query: zenoh.Query) -> None:
            self._guard(on_query, query)

        q = self._session.declare_queryable(key, zenoh.handlers.Callback(guarded))
        with self._lock:
            self._handles.append(q)

    def query_async(
        self,
        key: str,
        payload: bytes,
        on_answer: Callable[[Message | None, str | None], None],
        *,
        attachment: bytes | None = None,
        timeout_s: float = 10.0,
    ) -> None:
        """Send a query; ``on_answer(message, None)`` on the first good reply,
        ``on_answer(None, error)`` on an error reply or when none came within ``timeout_s``.
        """
        if self._closed:
            msg = f"{key}: the zenoh session is closed"
            raise BusError(msg)
        done = threading.Event()

        def on_reply(reply: zenoh.Reply) -> None:
            if done.is_set():
                return
            done.set()
            ok = reply.ok
            if ok is not None:
                att = ok.attachment
                message = Message(
                    str(ok.key_expr), ok.payload.to_bytes(), None if att is None else att.to_bytes()
                )
                on_answer(message, None)
            else:
                err = reply.err
                text = (
                    "error reply"
                    if err is None
                    else err.payload.to_bytes().decode(errors="replace")
                )
                on_answer(None, text)

        def on_end() -> None:
            if not done.is_set():
                done.set()
                on_answer(None, f"no answer within {timeout_s:g} s")

        def guarded_reply(reply: zenoh.Reply) -> None:
            self._guard(on_reply, reply)

        def guarded_end() -> None:
            self._guard(on_end)

        self._session.get(
            key,
            zenoh.handlers.Callback(guarded_reply, guarded_end),
            payload=payload,
            attachment=attachment,
            timeout=timeout_s,
            target=zenoh.QueryTarget.BEST_MATCHING,
            congestion_control=zenoh.CongestionControl.BLOCK,
        )

    def query(
        self,
        key: str,
        payload: bytes = b"",
        *,
        attachment: bytes | None = None,
        timeout_s: float = 5.0,
    ) -> Message:
        """Blocking query for one answer; BusError on an error reply or a timeout."""
        box: list[tuple[Message | None, str | None]] = []
        ready = threading.Event()

        def on_answer(message: Message | None, error: str | None) -> None:
            box.append((message, error))
            ready.set()

        self.query_async(key, payload, on_answer, attachment=attachment, timeout_s=timeout_s)
        ready.wait(timeout_s + 5.0)
        if not box:
            msg = f"{key}: no answer within {timeout_s:g} s"
            raise BusError(msg)
        message, error = box[0]
        if message is None:
            msg = f"{key}: {error}"
            raise BusError(msg)
        return message

    def _guard(self, fn: Callable[..., None], *args: Any) -> None:
        # An exception escaping into zenoh's thread is only printed; keep it for the owner.
        try:
            fn(*args)
        except Exception as err:
            self.callback_errors.append(f"{type(err).__name__}: {err}")

    def close(self) -> None:
        """Undeclare everything and close the session (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            handles, self._handles = self._handles, []
        for h in handles:
            with contextlib.suppress(Exception):
                h.undeclare()
        self._session.close()  # type: ignore[no-untyped-call]


OPEN_FAILED = "cannot open the zenoh session"  # the start of open_bus's error line


def open_bus(cfg: BusConfig) -> Bus:
    """Open a session (BusError with the endpoint when zenoh refuses, e.g. a port in use)."""
    conf = zenoh_config(cfg)
    try:
        session = zenoh.open(conf)
    except zenoh.ZError as err:
        listen = cfg.listen
        if listen is None and cfg.connect is None and cfg.config_file is None and cfg.serves:
            listen = (DEFAULT_ENDPOINT,)
        where = ", ".join((*(listen or ()), *(cfg.connect or ()))) or "default endpoints"
        msg = f"{OPEN_FAILED} ({cfg.mode}, {where}): {_one_line(err)}"
        raise BusError(msg) from None
    return Bus(session, cfg)
