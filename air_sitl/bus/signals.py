"""Run until SIGINT or SIGTERM: the life of the router and the bridges."""

from __future__ import annotations

import signal
import threading
from types import FrameType


def wait_until_signalled(stop: threading.Event | None = None) -> int:
    """Block the main thread until SIGINT/SIGTERM (or ``stop`` is set); the signal number or 0."""
    event = stop or threading.Event()
    got: list[int] = []

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        got.append(signum)
        event.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        while not event.wait(0.2):
            pass
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
    return got[0] if got else 0
