"""A real ``air-sitl serve`` process on loopback ports for a test, and the endpoints it offers.

The vehicle runs as a subprocess of the interpreter running the tests (``python -m air_sitl
serve``), exactly as a user would start it. MAVLink links bind port 0 (the kernel picks a
free port and the vehicle's start-up line says which); the zenoh listener takes a free port
picked here, tried again on another port when it was taken in between. Nothing is read from
or written to the default ports (14540, 14550, 7447), so tests can run side by side.
"""

from __future__ import annotations

import contextlib
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

READY = "vehicle ready"  # the start-up line of `air-sitl serve` once its links are open
_LOCAL = re.compile(r"(udpin|tcpin):[^ ]+ \(local ([^:]+):(\d+)\)")
START_TIMEOUT_S = float(os.environ.get("AIR_SITL_SERVE_TIMEOUT_S", "120"))
STOP_TIMEOUT_S = 20.0
START_TRIES = 3  # a zenoh port taken between picking and binding it: try another


class ServeError(RuntimeError):
    """``air-sitl serve`` exited or stayed silent before its vehicle was ready."""


@dataclass
class ServedVehicle:
    """A running ``air-sitl serve`` and where to reach it.

    ``mavlink_udp_port`` listens for clients (the vehicle answers whoever sends to it: a
    ground station's heartbeat is enough); ``mavlink_tcp_port`` accepts any number of TCP
    clients. ``zenoh_endpoint`` is the vehicle's zenoh listener, ``vehicle`` the key space
    name (``air/<vehicle>/...``).
    """

    process: subprocess.Popen[str]
    host: str
    mavlink_udp_port: int
    mavlink_tcp_port: int
    zenoh_endpoint: str
    vehicle: str
    banner: str
    _stdout: list[str] = field(default_factory=list)
    _stderr: list[str] = field(default_factory=list)

    @property
    def pymavlink_url(self) -> str:
        """Connection string for ``pymavlink.mavutil.mavlink_connection`` (UDP)."""
        return f"udpout:{self.host}:{self.mavlink_udp_port}"

    @property
    def pymavlink_tcp_url(self) -> str:
        """Connection string for ``pymavlink.mavutil.mavlink_connection`` (TCP)."""
        return f"tcp:{self.host}:{self.mavlink_tcp_port}"

    @property
    def mavsdk_url(self) -> str:
        """Connection string for MAVSDK's ``add_any_connection`` / ``System.connect`` (TCP)."""
        return f"tcpout://{self.host}:{self.mavlink_tcp_port}"

    @property
    def zenoh_key_prefix(self) -> str:
        """Every key of this vehicle starts with it (``air/uav0``)."""
        return f"air/{self.vehicle}"

    def output(self) -> tuple[str, str]:
        """What the vehicle printed so far: (stdout, stderr)."""
        return "".join(self._stdout), "".join(self._stderr)

    def stop(self) -> int:
        """Stop the vehicle as Ctrl-C does and wait for it; its exit code (0: a clean stop)."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
        try:
            self.process.wait(timeout=STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        return self.process.returncode


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port of ``host`` nobody holds right now (it may be taken before it is bound)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _drain(stream: object, into: list[str], ready: threading.Event | None) -> None:
    """Keep reading a pipe (so the vehicle never blocks on a full one); flag the ready line."""
    for line in iter(stream.readline, ""):  # type: ignore[attr-defined]
        into.append(line)
        if ready is not None and READY in line:
            ready.set()


def _start_once(args: Sequence[str], host: str, vehicle: str, zenoh_port: int) -> ServedVehicle:
    endpoint = f"tcp/{host}:{zenoh_port}"
    cmd = [
        sys.executable, "-m", "air_sitl", "serve",
        "--mavlink", f"udpin:{host}:0", "--mavlink", f"tcpin:{host}:0",
        "--zenoh", "--zenoh-listen", endpoint, "--vehicle", vehicle,
        *args,
    ]  # fmt: skip
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, bufsize=1
    )
    out: list[str] = []
    err: list[str] = []
    ready = threading.Event()
    for stream, lines, flag in ((proc.stdout, out, ready), (proc.stderr, err, None)):
        threading.Thread(target=_drain, args=(stream, lines, flag), daemon=True).start()
    deadline = time.monotonic() + START_TIMEOUT_S
    while not ready.wait(0.05):
        if proc.poll() is not None or time.monotonic() > deadline:
            if proc.poll() is None:
                proc.kill()
            proc.wait()
            time.sleep(0.1)  # let the readers take the last lines
            said = "".join(err).strip().splitlines()
            why = said[-1] if said else f"no '{READY}' line within {START_TIMEOUT_S:g} s"
            msg = f"air-sitl serve (exit {proc.returncode}): {why}"
            raise ServeError(msg)
    banner = next(line for line in out if READY in line)
    ports = {kind: (h, int(p)) for kind, h, p in _LOCAL.findall(banner)}
    if set(ports) != {"udpin", "tcpin"}:
        proc.kill()
        proc.wait()
        msg = f"air-sitl serve: no local ports in its start-up line: {banner.strip()}"
        raise ServeError(msg)
    return ServedVehicle(
        process=proc,
        host=host,
        mavlink_udp_port=ports["udpin"][1],
        mavlink_tcp_port=ports["tcpin"][1],
        zenoh_endpoint=endpoint,
        vehicle=vehicle,
        banner=banner.strip(),
        _stdout=out,
        _stderr=err,
    )


@contextlib.contextmanager
def served_vehicle(
    *args: str, host: str = "127.0.0.1", vehicle: str = "uav0"
) -> Iterator[ServedVehicle]:
    """Run ``air-sitl serve ARGS`` on free loopback ports until the block ends.

    ARGS are serve's own options (``--plan missions/UC-200.plan``, ``--speed 10``, ...); the
    links, the zenoh listener and the vehicle name are set here. Raises :class:`ServeError`
    with serve's own error line when it does not start.
    """
    served = None
    for attempt in range(START_TRIES):
        try:
            served = _start_once(args, host, vehicle, free_tcp_port(host))
            break
        except ServeError as failure:
            # Only a zenoh port taken in between is worth another try; anything else is final.
            if "zenoh" not in str(failure) or attempt == START_TRIES - 1:
                raise
    assert served is not None
    try:
        yield served
    finally:
        served.stop()
