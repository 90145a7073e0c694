"""Lockstep with an external estimator: ``--wait-for NAME[:MAX_LAG]``.

A :class:`~air_sitl.sinks.FrameSource` wrapper. Before frame ``k + MAX_LAG`` is submitted for
rendering, frame ``k`` is published (taken from the camera early if need be) and the
simulation thread waits until the estimate for frame ``k`` arrived; a silent estimator stops
the run with a :class:`BusError` after ``timeout_s`` of wall time. The frames are still handed
to every sink in order; the publisher sees they already went out and does not repeat them.

A lost connection (a router killed and restarted, a network cut) can swallow the awaited frame
or its estimate: every :data:`REOFFER_S` of wall time without the estimate, the frame is
offered again (``reoffer``); the estimators answer a repeat of their last frame with the same
estimate (an identical repeat is not a second row), so the flight goes on once the bus is back.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from air_sitl.bus.estimates import EstimateLog
from air_sitl.bus.publisher import FrameLedger
from air_sitl.errors import BusError
from air_sitl.sinks import FrameSource
from air_sitl.state import CameraFrame, SimSample

REOFFER_S = 2.0  # wall seconds without the awaited estimate before its frame goes out again


@dataclass(frozen=True, slots=True)
class WaitFor:
    """Which estimator to wait for, how far it may lag (frames), how long to wait (wall s)."""

    name: str
    max_lag: int = 1
    timeout_s: float = 10.0


class LockstepFrameSource:
    """Holds simulated time until the estimator ``wait.name`` keeps up with the frames."""

    def __init__(
        self,
        inner: FrameSource,
        *,
        wait: WaitFor,
        publish: Callable[[CameraFrame], None],
        ledger: FrameLedger,
        log: EstimateLog,
        image_key: str,
        subscriber_present: Callable[[], bool],
        reoffer: Callable[[CameraFrame], None] | None = None,
    ) -> None:
        self.inner = inner
        self.wait = wait
        self._publish = publish
        self._ledger = ledger
        self._log = log
        self._image_key = image_key
        self._subscriber_present = subscriber_present
        self._reoffer = reoffer
        self._unanswered: dict[int, CameraFrame] = {}  # published, estimate not yet awaited
        self._held: list[CameraFrame] = []  # published early, not yet handed to the runner
        self._first_submitted: int | None = None
        self._consumer_seen = False
        self.wait_wall_s = 0.0

    def submit(self, sample: SimSample, index: int) -> None:
        """Wait for the estimate of frame ``index - max_lag``, then queue frame ``index``."""
        target = index - self.wait.max_lag
        if self._first_submitted is not None and target >= self._first_submitted:
            self._publish_through(target)
            self._await(target)
        if self._first_submitted is None:
            self._first_submitted = index
        self.inner.submit(sample, index)

    def ready(self) -> list[CameraFrame]:
        """Frames done so far in order (publishing those not yet out)."""
        return self._take(self.inner.ready())

    def flush(self) -> list[CameraFrame]:
        """Every remaining frame, each published and answered (within the timeout)."""
        out = self._take(self.inner.flush())
        for frame in out:
            self._await(frame.index)
        return out

    def close(self) -> None:
        """Close the wrapped camera."""
        self.inner.close()

    def _take(self, frames: list[CameraFrame]) -> list[CameraFrame]:
        for frame in frames:
            self._publish_one(frame)
        out = [*self._held, *frames]
        self._held = []
        return out

    def _publish_one(self, frame: CameraFrame) -> None:
        if self._ledger.published(frame.index):
            return
        self.wait_for_consumer()
        self._publish(frame)
        self._unanswered[frame.index] = frame

    def wait_for_consumer(self) -> None:
        """Block until the estimator listens (once). Called before the flight's first sample is
        published too: a sample published before its subscription is live is lost, and the
        estimator would miss the IMU and GNSS of frame 0 (the first frame of an air start)."""
        if not self._consumer_seen:
            self._wait_for_subscriber()

    def _publish_through(self, target: int) -> None:
        """Make sure frame ``target`` went out (render it now if the camera is behind)."""
        if self._ledger.published(target):
            return
        frames = self.inner.ready()
        if not any(f.index >= target for f in frames):
            frames += self.inner.flush()
        for frame in frames:
            self._publish_one(frame)
        self._held.extend(frames)

    def _wait_for_subscriber(self) -> None:
        """Before the first frame: someone must listen, or frame 0 would be lost."""
        start = time.monotonic()
        while not self._subscriber_present():
            if time.monotonic() - start > self.wait.timeout_s:
                msg = (
                    f"--wait-for {self.wait.name}: nobody subscribed to {self._image_key} "
                    f"within {self.wait.timeout_s:g} s"
                )
                raise BusError(msg)
            time.sleep(0.01)
        self._consumer_seen = True
        self.wait_wall_s += time.monotonic() - start

    def _await(self, frame: int) -> None:
        start = time.monotonic()
        deadline = start + self.wait.timeout_s
        while not self._log.wait_for(
            self.wait.name, frame, max(0.0, min(REOFFER_S, deadline - time.monotonic()))
        ):
            if time.monotonic() >= deadline:
                msg = (
                    f"--wait-for {self.wait.name}: no estimate for frame {frame} within "
                    f"{self.wait.timeout_s:g} s of wall time (the estimator stopped?)"
                )
                raise BusError(msg)
            offered = self._unanswered.get(frame)
            if offered is not None and self._reoffer is not None:
                self._reoffer(offered)
        for index in [i for i in self._unanswered if i <= frame]:
            del self._unanswered[index]
        self.wait_wall_s += time.monotonic() - start
