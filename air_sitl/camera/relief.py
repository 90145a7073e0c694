"""Frames over relief: every pixel shows the FIRST surface its ray meets (ray marching).

Rays are marched over the surface's height field on the map's level-L pixel grid, from the
highest height in the footprint (or the camera) down to the lowest, in equal altitude steps
that move the ray by at most one level pixel; the first step under the surface is refined
by bisection and a secant (exact on a plane). So tall things lean away from the nadir and
hide what is behind them (a "project at the height found there" iteration would not
occlude). A wall shows the map's colour at its foot, stretched.

Speed: a coarse grid of rays (every ``STRIDE``-th pixel, half a stride beyond the image) is
marched; the grid is refined by halving the stride down to 2 only in cells next to a sample
where the parallax (pixels of lean) bends by more than ``EDGE_PX`` (roof edges, crowns,
occlusion boundaries); then every pixel of the remaining edge cells is solved on its own and
the rest is interpolated bilinearly (exact for a plane to far below a pixel). A new ray
inside a cell first tries the altitudes its cell's corners hit (``settle_ray``: one height
sample each, then up to three secant steps); only rays under the surface there (walls,
things no corner saw), or not settling, are marched over the corners' altitude range; new
samples whose corners all hit one height (within ``FLAT_M``) keep the interpolation. A
march skips 8-pixel tiles whose highest point is below the ray (a max-height tile per
window), steps one level pixel at a time near the surface, then refines. Then a remap
from the map window (in strips). The samples sit half a pixel off the pixel grid, so the
last step to full resolution is one ``cv2.resize``. The loops are compiled (``relief_march``,
numba, imported and compiled or loaded from its cache by :func:`warm` when a renderer over
relief is built, before the clock runs).

Cost (bench_camera.py part 4, this 2-core machine, flat in the same run, load average 5.6
falling to 3.4): 5.9 / 7.0 / 3.6x the flat render at 200 / 300 / 3000 m over the built-in
urban surface, 5.0 / 7.1 / 3.3x over it as a 1.2 m GeoTIFF DSM, 13.0 / 21.7 / 6.4x over the
rough forest canopy. The remap runs in strips, each from a copy of the map pixels it samples
where the mosaic is large (3000 m: 0.3-0.7 ms less a frame), and a thread keeps its last
three height windows (a frame's search may read two, which before were read again every
frame). At urban 200 m (about 5 ms a frame): the ground maps 3.5 ms (sample_grid 2.0 ms of
which 0.5 ms coarse grid and bookkeeping, then about 9,000 refinement rays at ~200 ns, and
9,000 edge pixels 1.1 ms), the remap 0.7 ms, geometry 0.2 ms. The forest needs 120,000 rays
a frame at 300 m (nearly every cell is an edge), and is approximate there: against a march
of every pixel, 20% of its pixels are off by more than 0.5 px (urban: 0.9%). Tried: each
new ray marched from the smallest nadir distance its cell's corners hit at (the first hit
moves outward with the angle from the nadir) cuts those to 4.8% (forest) and 0.26% (urban),
but costs twice the time. The 3x target needs fewer rays, not only faster ones.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.base import TILE_PX
from air_sitl.maps.surface import Heights, SurfaceModel

if TYPE_CHECKING:
    from types import ModuleType

F32 = npt.NDArray[np.float32]
STRIDE = 16  # image pixels between the coarse grid's rays
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
    tile_max: F32  # highest height of each relief_march.TILE-pixel tile


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
    tops = _kernels().tile_max(values)
    return HeightWindow(values, ax0, ay0, float(values.min()), float(values.max()), tops)


def march_one(window: HeightWindow, cx: float, cy: float, cam_z: float, ax: float,
              ay: float) -> float:  # fmt: skip
    """Altitude of the first surface point of one ray (level-pixel slopes ax, ay) between
    the window's highest point (or the camera) and its lowest."""
    top = float(np.float32(min(window.h_max, cam_z)))
    z, _found = _kernels().march_ray(
        window.values, window.tile_max, (cx - window.x0) + cam_z * ax,
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
) -> tuple[F32, F32, dict[str, float]]:
    """Level-pixel coordinates (relative to the window) of the surface each pixel sees.

    Returns ((height, width, 2) map x, y; (x min, y min, x max, y max) of them in each strip
    of ``rows`` image rows (0: one strip); stats of the march). Rays that never descend
    are the caller's to mask (sky). Samples sit at image points (STRIDE * j - PAD + 0.5,
    STRIDE * i - PAD + 0.5); each level halves the stride, interpolating midpoints and
    solving again only the cells whose corners' parallax differs by more than EDGE_PX.
    """
    k = _kernels()
    args = (
        window.values, window.tile_max, np.asarray(r, dtype=np.float64),
        np.asarray(jac, dtype=np.float64), float(1 << level), float(cx - window.x0),
        float(cy - window.y0), float(cam_z), window.h_min, window.h_max,
    )  # fmt: skip
    grid, edge, rays, solved = k.sample_grid(*args, width, height, STRIDE)
    # Full resolution: bilinear from the stride-2 grid (sample (j, i) is image point
    # (2i - pad + 0.5, 2j - pad + 0.5): cv2.resize's x2 grid puts output pixel x - pad at
    # input x / 2 - 0.25), then every pixel of a remaining edge cell solved on its own.
    pad = STRIDE // 2
    coarse = cv2.merge((grid[0], grid[1]))
    size = (2 * coarse.shape[1], 2 * coarse.shape[0])
    full: F32 = cv2.resize(coarse, size, interpolation=cv2.INTER_LINEAR)
    rows = rows if rows > 0 else height
    bounds = k.strip_bounds(grid, pad, height, rows)
    fixed = k.solve_edge_pixels(full, grid, edge, *args, pad, width, height, bounds, rows)
    stats = {"rays": float(rays), "rays_before_full": float(solved),
             "fixed_rays": float(solved + fixed)}  # fmt: skip
    return full[pad : pad + height, pad : pad + width], bounds, stats  # a view: remap takes it


def _kernels() -> ModuleType:
    """The compiled kernels, imported on first use: numba's import (about a second) and
    first compile are paid only by renderers over relief."""
    from air_sitl.camera import relief_march

    return relief_march


@functools.cache
def warm() -> None:
    """Compile every kernel a relief frame runs (or load it from numba's disk cache) through
    the very calls a frame makes, on a small window: a renderer over relief calls this when
    it is built, before the clock runs, so its first frame does not stall the render threads
    (seconds compiling after an install, about a second loading the cache)."""
    k = _kernels()
    values = np.zeros((2 * TILE_PX, 2 * TILE_PX), dtype=np.float32)
    values[TILE_PX:, :] = 5.0  # a step: edge cells, so every path of the grid is typed
    window = HeightWindow(values, 0, 0, 0.0, 5.0, k.tile_max(values))
    nadir = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)  # image (u, v, 1) -> NED, looking down
    ground_maps(window, nadir, (1.0, 0.0, 0.0, 1.0), 0, 8.0, 8.0, 100.0, 8, 8)
    march_one(window, 8.0, 8.0, 100.0, 0.01, 0.01)
