"""The camera bridge: turns 50 Hz poses into JPEG frames on a small pool of threads.

OpenCV's warp and JPEG encoder release the GIL, so worker threads render while the simulation
thread runs ahead. Frames come out strictly in submission order (the output stays
deterministic whatever the scheduling), and at most ``max_pending`` frames are in flight: when
the workers fall behind, ``submit`` waits for the oldest one (memory stays bounded).
:class:`OrderedPool` is that pool, whatever a job returns: a frame here, every map date's
frame of one tick for :class:`air_sitl.camera.same_grid.GridFrames`.
"""

from __future__ import annotations

import os
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Generic, TypeVar

import cv2

from air_sitl.camera.render import Renderer, render_camera_frame
from air_sitl.maps.choose import close_map
from air_sitl.state import CameraFrame, SimSample

T = TypeVar("T")


def default_workers() -> int:
    """One worker per core, at least one (2 on the reference machine)."""
    return max(1, min(4, os.cpu_count() or 1))


class OrderedPool(Generic[T]):
    """Jobs on ``workers`` threads (inline with 0), their results handed out in submission
    order, at most ``max_pending`` of them in flight."""

    def __init__(self, workers: int | None = None, *, max_pending: int = 16) -> None:
        self.workers = workers if workers is not None else default_workers()
        self.max_pending = max(1, max_pending)
        self._pool: ThreadPoolExecutor | None = None
        if self.workers > 0:
            # Our workers are the parallelism: OpenCV's own pool would oversubscribe the cores
            # and spin (sched_yield) waiting for work, costing more CPU than it saves.
            cv2.setNumThreads(1)
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="camera")
        self._pending: deque[Future[T]] = deque()
        self._done_sync: list[T] = []

    @property
    def in_flight(self) -> int:
        """Jobs submitted and not handed out yet."""
        return len(self._pending) + len(self._done_sync)

    def submit(self, job: Callable[[SimSample, int], T], sample: SimSample, index: int) -> None:
        """Queue ``job(sample, index)`` (run at once with ``workers=0``)."""
        if self._pool is None:
            self._done_sync.append(job(sample, index))
            return
        while len(self._pending) >= self.max_pending:
            # Back-pressure: wait for the oldest job; it is handed out by the next ready().
            self._done_sync.append(self._pending.popleft().result())
        self._pending.append(self._pool.submit(job, sample, index))

    def ready(self) -> list[T]:
        """Results so far, in order, without waiting past the first unfinished job."""
        out = self._done_sync
        self._done_sync = []
        while self._pending and self._pending[0].done():
            out.append(self._pending.popleft().result())
        return out

    def flush(self) -> list[T]:
        """Wait for every submitted job; return the rest in order."""
        out = self._done_sync
        self._done_sync = []
        while self._pending:
            out.append(self._pending.popleft().result())
        return out

    def close(self) -> None:
        """Stop the workers (pending jobs are dropped)."""
        for fut in self._pending:
            fut.cancel()
        self._pending.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class CameraBridge:
    """A :class:`air_sitl.sinks.FrameSource` rendering with a :class:`Renderer`."""

    def __init__(
        self, renderer: Renderer, *, workers: int | None = None, max_pending: int = 16
    ) -> None:
        self.renderer = renderer
        self._jobs: OrderedPool[CameraFrame] = OrderedPool(workers, max_pending=max_pending)
        self.workers = self._jobs.workers
        self.max_pending = self._jobs.max_pending

    @property
    def in_flight(self) -> int:
        """Frames submitted and not handed out yet."""
        return self._jobs.in_flight

    def _render(self, sample: SimSample, index: int) -> CameraFrame:
        return render_camera_frame(self.renderer, sample, index)

    def submit(self, sample: SimSample, index: int) -> None:
        """Queue frame ``index`` taken at ``sample`` (renders inline with ``workers=0``)."""
        self._jobs.submit(self._render, sample, index)

    def ready(self) -> list[CameraFrame]:
        """Frames completed so far, in order, without waiting past the first unfinished one."""
        return self._jobs.ready()

    def flush(self) -> list[CameraFrame]:
        """Wait for every submitted frame; return the rest in order."""
        return self._jobs.flush()

    def close(self) -> None:
        """Stop the workers (pending frames are dropped) and release the map."""
        self._jobs.close()
        close_map(self.renderer.map)
