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
occlusion boundaries), marching the new rays over their cell's corners' altitude range;
then every pixel of the remaining edge cells is marched on its own and the rest is
interpolated bilinearly (exact for a plane to far below a pixel). Then one remap from the
map window. Cost (bench_camera.py part 4): 11-31x the flat render on this machine, NumPy
per-ray work at about 0.3 us a ray being the floor; a compiled march would be the next step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.base import TILE_PX
from air_sitl.maps.surface import Heights, SurfaceModel

F32 = npt.NDArray[np.float32]
STRIDE = 16
EDGE_PX = 2.0  # a cell is re-marched where the parallax bends by more at a corner (px)
MAX_STEPS = 160
REFINE = 4  # bisection steps after the march, before the secant
GROUP_LOG2 = 3.0  # rays needing up to 8x fewer steps are marched apart (less work, more calls)
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
    """Heights of a level window: values, its top-left level pixel, their range."""

    values: Heights
    x0: int
    y0: int
    h_min: float
    h_max: float


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
    values = surface.heights(level, ax0, ay0, ax1 - ax0, ay1 - ay0)
    return HeightWindow(values, ax0, ay0, float(values.min()), float(values.max()))


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
    n = ax.shape[0]
    if n == 0:
        return np.empty(0, np.float32), np.empty(0, bool)
    span = np.maximum(z_top - z_bottom, 0.0).astype(np.float32)
    reach = span * np.hypot(ax, ay)  # level px travelled over the range
    # Rays needing few steps are marched apart from those needing many (powers of 8).
    need = np.ceil(np.log2(np.maximum(reach, 1.0)) / GROUP_LOG2).astype(np.int64)
    groups = np.nonzero(np.bincount(need))[0]
    if groups.size > 1:
        z_hit = np.empty(n, dtype=np.float32)
        found = np.empty(n, dtype=bool)
        for grp in groups.tolist():
            sel = np.nonzero(need == grp)[0]
            z_hit[sel], found[sel] = march(
                window, cx, cy, cam_z, ax[sel], ay[sel], z_top[sel], z_bottom[sel]
            )
        return z_hit, found
    steps = int(min(MAX_STEPS, max(1, math.ceil(float(reach.max())))))
    k = np.arange(steps + 1, dtype=np.float32)[None, :] / np.float32(steps)
    z = z_top[:, None] - span[:, None] * k  # (n, steps + 1)
    depth = np.float32(cam_z) - z
    ox, oy = np.float32(cx - window.x0), np.float32(cy - window.y0)
    mx = ox + depth * ax[:, None]
    my = oy + depth * ay[:, None]
    h = _sample(window.values, mx, my)
    below = z <= h
    found = below.any(axis=1)
    first = np.argmax(below, axis=1)
    rows = np.arange(n)
    prev = np.maximum(first - 1, 0)
    z_lo, z_hi = z[rows, first], z[rows, prev]  # first sample under the surface, last above
    f_lo, f_hi = z_lo - h[rows, first], z[rows, prev] - h[rows, prev]
    # Bisection between them, then the secant of (z - height) in the last bracket: exact on
    # a plane, and within 1/16 of a step anywhere.
    for _ in range(REFINE):
        zm = (z_hi + z_lo) * np.float32(0.5)
        d = np.float32(cam_z) - zm
        fm = zm - _sample(window.values, ox + d * ax, oy + d * ay)
        under = fm <= 0
        z_lo, f_lo = np.where(under, zm, z_lo), np.where(under, fm, f_lo)
        z_hi, f_hi = np.where(under, z_hi, zm), np.where(under, f_hi, fm)
    denom = f_hi - f_lo
    safe = np.where(denom > 1e-6, denom, 1.0)
    z_lo = np.where((first > 0) & (denom > 1e-6), z_lo + (z_hi - z_lo) * (-f_lo) / safe, z_lo)
    z_hit = np.where(found, z_lo, z_bottom).astype(np.float32)
    return z_hit, found


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
    are the caller's to mask (sky). Samples sit at pixels (STRIDE * j - PAD, STRIDE * i -
    PAD); each level halves the stride, interpolating midpoints and marching again only the
    cells whose corners' parallax differs by more than EDGE_PX.
    """
    st, pad = STRIDE, STRIDE // 2
    nx = -(-(width - 1 + pad) // st) + 1
    ny = -(-(height - 1 + pad) // st) + 1
    gu = np.arange(nx, dtype=np.float32) * st - pad
    gv = np.arange(ny, dtype=np.float32) * st - pad
    uu, vv = np.meshgrid(gu, gv)
    rays = ray_slopes(r, jac, level, uu.ravel(), vv.ravel())
    n = rays.ax.shape[0]
    z_top = np.full(n, min(window.h_max, cam_z), dtype=np.float32)
    z_bot = np.full(n, window.h_min, dtype=np.float32)
    z_hit, _ = march(window, cx, cy, cam_z, rays.ax, rays.ay, z_top, z_bot)
    ox, oy = np.float32(cx - window.x0), np.float32(cy - window.y0)
    depth = np.float32(cam_z) - z_hit
    slope = np.hypot(rays.ax, rays.ay)
    # Channels: map x, map y, hit altitude, level px per metre of height (parallax rate).
    grid = np.stack([ox + depth * rays.ax, oy + depth * rays.ay, z_hit, slope], axis=-1).reshape(
        ny, nx, 4
    )
    edge = _edges(grid, window.h_min)
    stats = {"rays": float(n), "edge_cells": float(edge.sum()), "fixed_rays": 0.0}
    while st > 2:
        grid, fresh = _upsample(grid), _fresh_samples(edge)
        st //= 2
        jj, ii = np.nonzero(fresh)
        if jj.size:
            zr = grid[:, :, 2]
            pj, pi = (jj // 2) * 2, (ii // 2) * 2
            pj1 = np.minimum(pj + 2, zr.shape[0] - 1)
            pi1 = np.minimum(pi + 2, zr.shape[1] - 1)
            corners = np.stack([zr[pj, pi], zr[pj, pi1], zr[pj1, pi], zr[pj1, pi1]])
            top, bot = _range(corners, window, cam_z)
            u = (ii * st - pad).astype(np.float32)
            v = (jj * st - pad).astype(np.float32)
            fine = ray_slopes(r, jac, level, u, v)
            z_fix, ok = march(window, cx, cy, cam_z, fine.ax, fine.ay, top, bot)
            d = np.float32(cam_z) - z_fix
            grid[jj, ii, 0] = np.where(ok, ox + d * fine.ax, grid[jj, ii, 0])
            grid[jj, ii, 1] = np.where(ok, oy + d * fine.ay, grid[jj, ii, 1])
            grid[jj, ii, 2] = np.where(ok, z_fix, grid[jj, ii, 2])
            grid[jj, ii, 3] = np.hypot(fine.ax, fine.ay)
            stats["fixed_rays"] += float(jj.size)
        # Only cells inside an edge cell of the coarser level can be edges now.
        edge = _edges(grid, window.h_min) & np.repeat(np.repeat(edge, 2, 0), 2, 1)
    # Full resolution: bilinear from the stride-2 grid (sample (j, i) is pixel (2i - pad,
    # 2j - pad)), then every pixel of a remaining edge cell marched on its own.
    stats["rays_before_full"] = stats["fixed_rays"]
    full = _upsample(np.ascontiguousarray(grid[:, :, :2]))
    maps = np.ascontiguousarray(full[pad : pad + height, pad : pad + width])
    if edge.any():
        zr = grid[:, :, 2]
        ej, ei = np.nonzero(edge)
        # The cell's own sample (offset 0, 0) is exact already: its three other pixels.
        py = (ej[:, None] * st - pad + np.array([[0, 1, 1]])).ravel()
        px = (ei[:, None] * st - pad + np.array([[1, 0, 1]])).ravel()
        corners = np.stack([zr[ej, ei], zr[ej, ei + 1], zr[ej + 1, ei], zr[ej + 1, ei + 1]])
        top, bot = _range(corners, window, cam_z)
        top, bot = np.repeat(top, 3), np.repeat(bot, 3)
        keep = (px >= 0) & (py >= 0) & (px < width) & (py < height)
        px, py, top, bot = px[keep], py[keep], top[keep], bot[keep]
        fine = ray_slopes(r, jac, level, px.astype(np.float32), py.astype(np.float32))
        z_fix, ok = march(window, cx, cy, cam_z, fine.ax, fine.ay, top, bot)
        d = np.float32(cam_z) - z_fix[ok]
        maps[py[ok], px[ok], 0] = ox + d * fine.ax[ok]
        maps[py[ok], px[ok], 1] = oy + d * fine.ay[ok]
        stats["fixed_rays"] += float(px.size)
    return maps, stats


def _range(corners: F32, window: HeightWindow, cam_z: float) -> tuple[F32, F32]:
    """Altitudes to march between for rays inside a cell: around its corners' hits."""
    top = np.minimum(corners.max(axis=0) + np.float32(1.0), np.float32(window.h_max))
    top = np.minimum(top, np.float32(cam_z))
    bot = np.maximum(corners.min(axis=0) - np.float32(0.25), np.float32(window.h_min))
    return top, bot


def _edges(grid: F32, h_min: float) -> npt.NDArray[np.bool_]:
    """Cells next to a sample where the parallax bends by more than EDGE_PX.

    The second difference of the parallax (pixels of lean) along rows and columns: zero on
    a plane or a steady slope, where interpolation is exact; large at steps (roof edges,
    occlusion boundaries) and on rough surfaces.
    """
    par = (grid[:, :, 2] - np.float32(h_min)) * grid[:, :, 3]
    bend = np.zeros_like(par)
    bend[:, 1:-1] = np.abs(par[:, :-2] - 2 * par[:, 1:-1] + par[:, 2:])
    np.maximum(
        bend[1:-1, :], np.abs(par[:-2, :] - 2 * par[1:-1, :] + par[2:, :]), out=bend[1:-1, :]
    )
    hot = bend > EDGE_PX
    edge: npt.NDArray[np.bool_] = hot[:-1, :-1] | hot[:-1, 1:] | hot[1:, :-1] | hot[1:, 1:]
    return edge


def _upsample(grid: F32) -> F32:
    """Nested x2 upsampling: old samples kept, midpoints and centres averaged (bilinear)."""
    ny, nx, c = grid.shape
    out = np.empty((2 * ny - 1, 2 * nx - 1, c), dtype=np.float32)
    out[::2, ::2] = grid
    out[::2, 1::2] = (grid[:, :-1] + grid[:, 1:]) * np.float32(0.5)
    out[1::2, :] = (out[:-2:2, :] + out[2::2, :]) * np.float32(0.5)
    return out


def _fresh_samples(edge: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Samples of the x2 grid that are new inside the given coarse cells."""
    cy, cx = edge.shape
    mask = np.zeros((2 * cy + 1, 2 * cx + 1), dtype=bool)
    j, i = np.nonzero(edge)
    for dj, di in ((1, 0), (0, 1), (1, 1), (2, 1), (1, 2)):
        mask[2 * j + dj, 2 * i + di] = True
    return mask


def _sample(values: Heights, mx: F32, my: F32) -> F32:
    """Bilinear heights at level pixels (mx, my) of any shape (edges repeat outward).

    NumPy gathers for few points (remap's set-up costs more there), remap for many.
    """
    shape = mx.shape
    n = mx.size
    if n < 16384:
        h, w = values.shape
        x = np.clip(mx.ravel(), 0.0, w - 1.001)
        y = np.clip(my.ravel(), 0.0, h - 1.001)
        ix, iy = x.astype(np.int64), y.astype(np.int64)
        fx, fy = x - ix, y - iy
        flat = values.ravel()
        i = iy * w + ix
        top = flat[i] * (1 - fx) + flat[i + 1] * fx
        bottom = flat[i + w] * (1 - fx) + flat[i + w + 1] * fx
        got: F32 = (top * (1 - fy) + bottom * fy).astype(np.float32).reshape(shape)
        return got
    cols = 4096  # remap wants fewer than 32767 rows and columns
    rows = -(-n // cols)
    fx = np.zeros(rows * cols, dtype=np.float32)
    fy = np.zeros(rows * cols, dtype=np.float32)
    fx[:n] = mx.ravel()
    fy[:n] = my.ravel()
    out = cv2.remap(
        values,
        fx.reshape(rows, cols),
        fy.reshape(rows, cols),
        interpolation=cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    result: F32 = np.asarray(out, dtype=np.float32).ravel()[:n].reshape(shape)
    return result
