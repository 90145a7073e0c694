"""One camera tick rendered over several maps of one grid: the dates of a map (issue 34).

Maps that differ only in what they show (the dates of a procedural world: the same lattice,
CRS, ground elevation and pyramid) give a frame the same geometry: its homography, pyramid
level, mosaic area and map pixel depend on the pose and the grid, not on the pixels. The
same camera and seed give it the same noise. :class:`GridFrames` renders each map's frame of a
tick in one job: the geometry computed once, the noise bank and the frame's slice of it shared,
then each map's own warp, noise and JPEG; every frame is the bytes its map's
:func:`~air_sitl.camera.render.render_camera_frame` gives (the geometry and the noise are pure
functions of what the maps share). Maps that do not share a grid are rendered each alone.
:class:`GridCamera` runs those jobs on one :class:`~air_sitl.camera.bridge.OrderedPool`, so
that the dates' frames take the cores' threads, not a pool of threads each.
"""

from __future__ import annotations

from collections.abc import Sequence

from air_sitl.camera.bridge import CameraBridge, OrderedPool
from air_sitl.camera.render import Renderer, camera_frame, render_camera_frame
from air_sitl.state import CameraFrame, SimSample


def same_grid(a: Renderer, b: Renderer) -> bool:
    """Whether ``a`` and ``b`` give every pose the same frame geometry and noise: the same
    camera and seed, flat ground (relief is each map's own surface), and maps of one kind
    on one grid (lattice, CRS, ground elevation, pyramid)."""
    return (
        a.camera == b.camera
        and a.seed == b.seed
        and a.surface is None
        and b.surface is None
        and type(a.map) is type(b.map)
        and a.map.georef == b.map.georef
        and a.map.ground_elevation_m == b.map.ground_elevation_m
        and a.map.num_levels == b.map.num_levels
    )


class GridFrames:
    """Renders one tick's frame over each of ``renderers``' maps (see the module docstring)."""

    def __init__(self, renderers: Sequence[Renderer]) -> None:
        self.renderers = list(renderers)
        first = self.renderers[0]
        self.shared = all(same_grid(first, r) for r in self.renderers[1:])
        if self.shared:
            for r in self.renderers[1:]:
                r.share_noise(first)

    def render(self, sample: SimSample, index: int) -> list[CameraFrame]:
        """Frame ``index`` taken at ``sample``, one per map, in the renderers' order (on one
        grid, a map much coarser than the camera is told once, by the first map's renderer:
        the maps share their pixel size)."""
        if not self.shared:
            return [render_camera_frame(r, sample, index) for r in self.renderers]
        first = self.renderers[0]
        state = sample.state
        tick = sample.camera
        in_window = tick is None or tick.capture_index is not None  # as render_camera_frame
        g = first.geometry(state, warn=in_window)
        c = g.center_map_px
        xy = (-1, -1) if c is None else (round(c[0]), round(c[1]))
        return [
            camera_frame(r, sample, index, r.encode(r.render(state, g, noise_index=index)), xy)
            for r in self.renderers
        ]


class GridCamera:
    """The cameras of several maps as one source of per-tick frame lists, on one pool of
    ``workers`` threads (the cameras' own pools stay unused; :meth:`close` closes them and
    their maps)."""

    def __init__(
        self, cameras: Sequence[CameraBridge], *, workers: int | None = None, max_pending: int = 16
    ) -> None:
        self._cameras = list(cameras)
        self._frames = GridFrames([c.renderer for c in self._cameras])
        self._jobs: OrderedPool[list[CameraFrame]] = OrderedPool(workers, max_pending=max_pending)

    def submit(self, sample: SimSample, index: int) -> None:
        """Queue tick ``index`` taken at ``sample`` for every map."""
        self._jobs.submit(self._frames.render, sample, index)

    def ready(self) -> list[list[CameraFrame]]:
        """Ticks rendered so far, in order (each: one frame per map), without waiting."""
        return self._jobs.ready()

    def flush(self) -> list[list[CameraFrame]]:
        """Wait for every submitted tick; return the rest in order."""
        return self._jobs.flush()

    def close(self) -> None:
        """Stop the workers, then close each camera (its map)."""
        self._jobs.close()
        for camera in self._cameras:
            camera.close()
