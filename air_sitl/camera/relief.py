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
window), steps one level pixel at a time near the surface, then refines. Then one remap
from the map window. The samples sit half a pixel off the pixel grid, so the last step to
full resolution is one ``cv2.resize``. The loops are compiled (``relief_march``, numba,
imported on the first frame over relief).

Cost (bench_camera.py part 4, this 2-core machine under load 11-13, flat and the NumPy
version of this design measured in the same run): 4.9 / 5.4 / 5.3x the flat render at
200 / 300 / 3000 m over the built-in urban surface (NumPy 10.2 / 10.7 / 9.3x), 5.3 / 5.5 /
3.6x over it as a 1.2 m GeoTIFF DSM (11.5 / 11.1 / 8.1x), 11.7 / 19.7 / 6.4x over the rough
forest canopy (22.8 / 39.7 / 12.2x). At urban 200 m (5.2 ms a frame): the ground maps 3.6 ms
(about 19,000 rays at 70-120 ns each, a fifth of them falling back to a march), the remap of
the map window 0.7-1.7 ms (about the whole flat render), the geometry 0.2 ms. The forest
needs 120,000 rays a frame at 300 m (nearly every cell is an edge), and is approximate
there: against a march of every pixel, 20% of its pixels are off by more than 0.5 px (urban:
0.9%). The 3x target needs fewer rays, not faster ones: a march of every pixel costs 60-70
ms; a sweep along the image lines through the nadir point (where the first hit moves
monotonically outward, so each ray starts where the previous one hit) is the candidate.
"""

from __future__ import annotations

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


def march(
    window: HeightWindow,
    cx: float,
    cy: float,
    cam_z: float,
    ax: F32,
    ay: F32,
    z_top: F32,
    z_bottom: F32,
) -> tuple[F32, npt.NDArray[np.bool_]]:
    """Altitude of the first surface point of each ray within [z_bottom, z_top].

    Returns (z_hit, found): rays already under the surface at z_top hit there; rays still
    above it at z_bottom are not found (their z_hit is z_bottom).
    """
    cam = np.float64(cam_z)
    px0 = (cx - window.x0) + cam * ax.astype(np.float64)  # the ray at altitude z: p0 - z * a
    py0 = (cy - window.y0) + cam * ay.astype(np.float64)
    f64 = np.float64
    return _kernels().march_rays(  # type: ignore[no-any-return]
        window.values, window.tile_max, px0, py0, ax.astype(f64), ay.astype(f64),
        z_top.astype(f64), z_bottom.astype(f64),
    )  # fmt: skip


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
) -> tuple[F32, dict[str, float]]:
    """Level-pixel coordinates (relative to the window) of the surface each pixel sees.

    Returns ((height, width, 2) map x, y; stats of the march). Rays that never descend
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
    fixed = k.solve_edge_pixels(full, grid, edge, *args, pad, width, height)
    stats = {"rays": float(rays), "rays_before_full": float(solved),
             "fixed_rays": float(solved + fixed)}  # fmt: skip
    return full[pad : pad + height, pad : pad + width], stats  # a view: remap takes it


def _kernels() -> ModuleType:
    """The compiled kernels, imported on first use: numba's import (about a second) and
    first compile are paid only by frames over relief."""
    from air_sitl.camera import relief_march

    return relief_march
