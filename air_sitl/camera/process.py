"""A camera rendering in a process of its own (a FrameSource): its Python (a procedural map's
tiles, the warps' set-up) never holds the interpreter lock the simulation thread needs.

``serve --foxglove`` renders the view's images with it: at ``--speed 10`` a render thread in
the simulation's process takes the lock for milliseconds at a time and the paced simulation,
which must step every half millisecond, falls behind. The process is spawned (the simulation
process runs threads: no fork), opens the same map, camera and seed, and answers each
``(sample, index)`` with its CameraFrame, in order. It runs at the lowest priority: where the
cores are short it gets what the simulation leaves, and the caller skips what it cannot take.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
from multiprocessing.connection import Connection

from air_sitl.camera.model import CameraModel
from air_sitl.options import MapChoice
from air_sitl.state import CameraFrame, GeoPoint, SimSample
from air_sitl.workers import die_with_parent

STOP_TIMEOUT_S = 10.0
NICE = 19  # the process's priority: the lowest (a best-effort camera)


def _render_loop(
    conn: Connection, choice: MapChoice, home: GeoPoint, name: str, camera: CameraModel, seed: int
) -> None:
    """The child: render each (sample, index) received, send the frame back; None stops.
    At the lowest priority: where the cores are short, the simulation runs first. Like the
    other workers, it leaves Ctrl-C (sent to the whole process group) to its parent, which
    stops it, and dies with it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    die_with_parent()
    with contextlib.suppress(OSError):
        os.nice(NICE)
    from air_sitl.camera.options import open_chosen_renderer
    from air_sitl.camera.render import render_camera_frame
    from air_sitl.maps.choose import close_map, open_chosen_map

    renderer = open_chosen_renderer(choice, open_chosen_map(choice, home, name), camera, seed)
    try:
        while (item := conn.recv()) is not None:
            sample, index = item
            conn.send(render_camera_frame(renderer, sample, index))
    except (EOFError, OSError):
        pass  # the parent went away
    finally:
        close_map(renderer.map)


class ProcessCamera:
    """Renders in a spawned process; frames come back in submission order. If the process
    dies (a render failed), its frames stop: ``failed`` says so."""

    def __init__(
        self, choice: MapChoice, home: GeoPoint, name: str, camera: CameraModel, seed: int
    ) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self._proc = ctx.Process(
            target=_render_loop,
            args=(child, choice, home, name, camera, seed),
            name="air-sitl camera",
            daemon=True,
        )
        self._proc.start()
        child.close()
        self.in_flight = 0  # submitted, not yet returned
        self.failed = False

    def submit(self, sample: SimSample, index: int) -> None:
        """Send frame ``index`` taken at ``sample`` to the process (returns at once)."""
        if self.failed:
            return
        try:
            self._conn.send((sample, index))
            self.in_flight += 1
        except OSError:
            self.failed = True

    def _take(self, wait: bool) -> list[CameraFrame]:
        out: list[CameraFrame] = []
        try:
            while self.in_flight and (wait or self._conn.poll()):
                out.append(self._conn.recv())
                self.in_flight -= 1
        except (EOFError, OSError):
            self.failed = True
            self.in_flight = 0
        return out

    def ready(self) -> list[CameraFrame]:
        """Frames rendered so far, without waiting."""
        return self._take(wait=False)

    def flush(self) -> list[CameraFrame]:
        """Wait for every submitted frame."""
        return self._take(wait=True)

    def close(self) -> None:
        """Stop the process (frames still rendering are dropped)."""
        with contextlib.suppress(OSError):
            self._conn.send(None)
        self._proc.join(STOP_TIMEOUT_S)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(STOP_TIMEOUT_S)
        self._conn.close()
