"""Ports for the tests' own servers and clients, never one another xdist worker may take.

A port picked by binding port 0 and closing the socket is in the kernel's ephemeral range,
where the other worker's connections and bind(0) calls land too, and stays free only by
luck until the program that needs it binds it (after its imports, seconds later). Each worker
takes its ports from a range of its own below the ephemeral range (32768-60999 on Linux),
moving on through it, and checks each one by binding it.
"""

from __future__ import annotations

import itertools
import os
import socket

BASE = 20_000
SPAN = 1_000  # ports per worker: workers gw0..gw9 use 20000-29999
_cursor = itertools.count()


def _worker_index() -> int:
    name = os.environ.get("PYTEST_XDIST_WORKER", "")  # gw0, gw1, ...; unset without xdist
    digits = name.removeprefix("gw")
    return int(digits) % 10 if digits.isdigit() else 0


def free_port(kind: socket.SocketKind = socket.SOCK_STREAM) -> int:
    """A loopback port of this worker's range that nothing holds right now (TCP or UDP)."""
    first = BASE + SPAN * _worker_index()
    for _ in range(SPAN):
        port = first + next(_cursor) % SPAN
        with socket.socket(socket.AF_INET, kind) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        return port
    msg = f"no free port in {first}-{first + SPAN - 1}"
    raise RuntimeError(msg)
