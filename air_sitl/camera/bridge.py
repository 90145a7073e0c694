"""The camera bridge: turns 50 Hz poses into JPEG frames on a small pool of threads.

OpenCV's warp and JPEG encoder release the GIL, so worker threads render while the simulation
thread runs ahead. Frames come out strictly in submission order (the output stays
deterministic whatever the scheduling), and at most ``max_pending`` frames are in flight: when
the workers fall behind, ``submit`` waits for the oldest one (memory stays bounded).
"""

from __future__ import annotations

import os
from collections import deque
from concurrent.futures import Future, ThreadPoolExecutor

import cv2

from air_sitl.camera.render import Renderer, render_camera_frame
from air_sitl.maps.choose import close_map
from air_sitl.state import CameraFrame, SimSample


def default_workers() -> int:
    """One worker per core, at least one (2 on the reference machine)."""
    return max(1, min(4, os.cpu_count() or 1))


class CameraBridge:
    """A :class:`air_sitl.sinks.FrameSource` rendering with a :class:`Renderer`."""

    def __init__(
        self, renderer: Renderer, *, workers: int | None = None, max_pending: int = 16
    ) -> None:
        self.renderer = renderer
        self.workers = workers if workers is not None else default_workers()
        self.max_pending = max(1, max_pending)
        self._pool: ThreadPoolExecutor | None = None
        if self.workers > 0:
            # Our workers are the parallelism: OpenCV's own pool would oversubscribe the cores
            # and spin (sched_yield) waiting for work, costing more CPU than it saves.
            cv2.setNumThreads(1)
            self._pool = ThreadPoolExecutor(self.workers, thread_name_prefix="camera")
        self._pending: deque[Future[CameraFrame]] = deque()
        self._done_sync: list[CameraFrame] = []

    def submit(self, sample: SimSample, index: int) -> None:
        """Queue frame ``index`` taken at ``sample`` (renders inline with ``workers=0``)."""
        if self._pool is None:
            self._done_sync.append(render_camera_frame(self.renderer, sample, index))
            return
        while len(self._pending) >= self.max_pending:
            # Back-pressure: wait for the oldest frame; it is handed out by the next ready().
            self._done_sync.append(self._pending.popleft().result())
        self._pending.append(self._pool.submit(render_camera_frame, self.renderer, sample, index))

    def ready(self) -> list[CameraFrame]:
        """Frames completed so far, in order, without waiting past the first unfinished one."""
        out = self._done_sync
        self._done_sync = []
        while self._pending and self._pending[0].done():
            out.append(self._pending.popleft().result())
        return out

    def flush(self) -> list[CameraFrame]:
        """Wait for every submitted frame; return the rest in order."""
        out = self._done_sync
        self._done_sync = []
        while self._pending:
            out.append(self._pending.popleft().result())
        return out

    def close(self) -> None:
        """Stop the workers (pending frames are dropped) and release the map."""
        for fut in self._pending:
            fut.cancel()
        self._pending.clear()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        close_map(self.renderer.map)
