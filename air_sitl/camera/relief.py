"""Frames over relief: every pixel shows the FIRST surface its ray meets, exactly.

The surface is the bilinear interpolation of the surface model's posts on the map's level-L
pixel grid (the level the frame takes its colours from). Each pixel's ray walks the cells
it crosses from the top of the height range down, and the first cell whose bilinear patch
it meets gives the hit by solving a quadratic (``relief_march.walk_rays``): so tall things
lean away from the nadir and hide what is behind them, crowns keep their outline, and no
ground shows through at their edges. A wall shows the map's colour at its foot, stretched.

Speed: blocks of 16 x 16 pixels first descend together: at one altitude a block's rays lie
inside the quadrilateral of its corner rays, so the block comes down, a tile's height at a
time, while every 8 x 8-cell tile under the box of those corners is lower (a max-height
tile grid per window). Then each ray walks alone from there, passing every cell whose
highest post is below it where it leaves the cell (a grid walk without divisions), and
solves only the patches it may meet: over the forest about 5 cells and 1.5 patches a ray,
over the town about 2-3 and 1.1. The cost is the latency of each ray's chain of dependent
steps, and a mispredicted branch at the end of one walk stalls the next until its start is
computed; so a block's rays and their walks' starts are computed first, in loops the
compiler turns into vector code, and the walks then start from numbers in the core's
cache; cell indices are unsigned (no test for negative indices). A window's posts, cell
tops and tile tops are read once and kept by the thread for the next frames (a frame's
search may read two windows). Rays that leave the window before reaching the lowest height
(views toward the horizon, where the window is clipped) are marched by fine steps instead
(a one-pixel step and bisection). Then a remap from the map window (in strips, each from a
copy of the map pixels it samples where the mosaic is large). The loops are compiled
(``relief_march``, ``air_sitl.compiled``: imported, and where numba's JIT compiles them
compiled or loaded from its cache, by :func:`warm` when a renderer over relief is built,
before the clock runs). Tried and slower here: a
second max-height grid of 4-cell tiles skipped per ray, 4 x 4-pixel blocks (or 4 x 4
sub-blocks descending further inside a block), two rays walked in one loop, rays walked in
lock-step a cell at a time (state in arrays), the patches solved in a pass of their own,
the walk stepping along the major axis or without branches, one flat cell index.

Cost (``bench_camera.py --relief-only --frames 100``, one render thread, 640 x 480, load
average 6.2-7.8 on this 2-core machine, two runs; CPU time of the process, per core): at
200 / 300 / 3000 m, urban 11.3 / 12.1 / 10.7 ms a frame (88 / 83 / 94 frames/s; 11-13x
the flat render of the same frames, 0.9-1.0 ms), forest 16.1 / 19.3 / 14.5 ms (62 / 52 /
69 frames/s), urban over a 1.2 m GeoTIFF DSM 11.4 / 12.0 / 10.8 ms (88 / 83 / 92
frames/s); wall clock within 2 % of these in those runs.
Of a forest frame at 300 m about 17.5 ms are the rays (``relief_march.hit_maps``; before
this layout 23.5 ms: 2 the rays and blocks, 9.5 the walks up to the first cell a ray may
meet, 9.5 the patches and the walks after a miss), 2 ms the remap and the noise. The bench
also prints wall-clock figures, which the machine's other load stretches.

Until issue 24 an adaptive grid (rays on a 16-pixel grid, refined at parallax edges and
interpolated elsewhere) was used: cheaper, but 9-14 % of the forest's pixels (15-22 % in
an image corner) were more than 0.5 px from the first hit (blobby crowns, ground showing
through at their edges), 0.5-6 % of the town's.
Figures of the exact walk: ``benchmarks/bench_camera.py --relief-only``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from air_sitl.maps.base import TILE_PX
from air_sitl.maps.surface import Heights, SurfaceModel

if TYPE_CHECKING:
    from types import ModuleType

F32 = npt.NDArray[np.float32]
_MIN_DOWN = 1e-6


@dataclass(frozen=True, slots=True)
class Rays:
    """Rays as straight lines over the level grid, parametrised by altitude z (m AMSL).

    The ray at altitude z is at level pixel (cx + (top_m - z) * ax, cy + (top_m - z) * ay);
    ``down`` is False where the ray never descends (sky).
    """

    ax: F32
    ay: F32
    down: npt.NDArray[np.bool_]


@dataclass(frozen=True, slots=True)
class HeightWindow:
    """Heights of a level window: values, its top-left level pixel, their range, tile tops."""

    values: Heights
    x0: int
    y0: int
    h_min: float
    h_max: float
    tile_max: F32  # highest post of each relief_march.TILE-cell tile
    cell_max: F32  # highest of the four posts of each cell


def ray_slopes(
    r: tuple[float, ...], jac: tuple[float, float, float, float], level: int, u: F32, v: F32
) -> Rays:
    """Level pixels travelled per metre of descent, for image points (u, v)."""
    s = float(1 << level)
    dn = r[0] * u + r[1] * v + r[2]
    de = r[3] * u + r[4] * v + r[5]
    dd = r[6] * u + r[7] * v + r[8]
    down = dd > _MIN_DOWN
    inv = np.where(down, 1.0 / np.where(down, dd, 1.0), 0.0).astype(np.float32)
    ax = ((jac[0] * dn + jac[1] * de) / s * inv).astype(np.float32)
    ay = ((jac[2] * dn + jac[3] * de) / s * inv).astype(np.float32)
    return Rays(ax, ay, down)


def read_window(
    surface: SurfaceModel, level: int, x0: int, y0: int, x1: int, y1: int
) -> HeightWindow:
    """Heights covering level pixels [x0, x1] x [y0, y1], snapped out to whole tiles."""
    t = TILE_PX
    ax0, ay0 = (x0 // t) * t, (y0 // t) * t
    ax1, ay1 = -(-(x1 + 1) // t) * t, -(-(y1 + 1) // t) * t
    values = np.ascontiguousarray(surface.heights(level, ax0, ay0, ax1 - ax0, ay1 - ay0),
                                  dtype=np.float32)  # fmt: skip
    return _window(values, ax0, ay0)


def _window(values: Heights, x0: int, y0: int) -> HeightWindow:
    """A HeightWindow of ``values`` (float32, contiguous) at level pixel (x0, y0)."""
    k = _kernels()
    return HeightWindow(
        values, x0, y0, float(values.min()), float(values.max()), k.tile_max(values),
        k.cell_max(values),
    )  # fmt: skip


def march_one(window: HeightWindow, cx: float, cy: float, cam_z: float, ax: float,
              ay: float) -> float:  # fmt: skip
    """Altitude of the first surface point of one ray (level-pixel slopes ax, ay) between
    the window's highest point (or the camera) and its lowest."""
    top = float(np.float32(min(window.h_max, cam_z)))
    z, _found = _kernels().first_hit(
        window.values, window.cell_max, window.tile_max, (cx - window.x0) + cam_z * ax,
        (cy - window.y0) + cam_z * ay, ax, ay, top, window.h_min,
    )  # fmt: skip
    return float(np.float32(z))  # as the float32 arrays of rays did before


def ground_maps(
    window: HeightWindow,
    r: tuple[float, ...],
    jac: tuple[float, float, float, float],
    level: int,
    cx: float,
    cy: float,
    cam_z: float,
    width: int,
    height: int,
    rows: int = 0,
) -> tuple[F32, F32]:
    """Level-pixel coordinates (relative to the window) of the surface each pixel sees.

    Returns ((height, width, 2) map x, y; (x min, y min, x max, y max) of them in each strip
    of ``rows`` image rows (0: one strip)). Rays that never descend are the caller's to
    mask (sky).
    """
    rows = rows if rows > 0 else height
    maps = np.empty((height, width, 2), dtype=np.float32)
    bounds = np.empty((-(-height // rows), 4), dtype=np.float32)
    _kernels().hit_maps(
        window.values, window.cell_max, window.tile_max, np.asarray(r, dtype=np.float64),
        np.asarray(jac, dtype=np.float64), float(1 << level), float(cx - window.x0),
        float(cy - window.y0), float(cam_z), window.h_min, window.h_max, width, height, rows,
        maps, bounds,
    )  # fmt: skip
    return maps, bounds


def _kernels() -> ModuleType:
    """The compiled kernels, imported on first use: their load (and their first compile, or
    numba's import where its JIT compiles them) is paid only by renderers over relief."""
    from air_sitl.camera import relief_march

    return relief_march


@functools.cache
def warm() -> None:
    """Run every kernel a relief frame runs through the very calls a frame makes, on a small
    window: where numba's JIT compiles them, this compiles them (seconds after an install)
    or loads them from its disk cache (about a second); a renderer over relief calls this
    when it is built, before the clock runs, so its first frame does not stall the render
    threads."""
    values = np.zeros((2 * TILE_PX, 2 * TILE_PX), dtype=np.float32)
    values[TILE_PX:, :] = 5.0  # a step: every path of the walk is typed
    window = _window(values, 0, 0)
    nadir = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # image (u, v, 1) -> NED, looking down
    ground_maps(window, nadir, (1.0, 0.0, 0.0, 1.0), 0, 8.0, 8.0, 100.0, 8, 8)
    march_one(window, 8.0, 8.0, 100.0, 0.01, 0.01)
