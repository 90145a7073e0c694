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
inside a cell first tries the altitudes its cell's corners hit (:func:`settle`: one height
sample each, then a secant step); only rays under the surface there (walls, things no corner
saw), or not settling, are marched over the corners' altitude range. Then one remap from the
map window. The samples sit half a pixel off the pixel grid, so the last step to full
resolution is one ``cv2.resize``. A march is a few large array operations: its rays at once
as (steps, rays) arrays, heights sampled by one ``cv2.remap`` over rows of 4096 samples (a
remap over thousands of short rows costs ten times more).

Cost (bench_camera.py part 4, this 2-core machine under load): 8-13x the flat render over
the built-in urban surface, 6-12x over it as a 1.2 m GeoTIFF DSM, 11-20x over the rough
forest canopy, where nearly every cell is an edge (10-27x before the settle pass). What is
left is NumPy work and call overhead over 6,000-70,000 rays per frame; the 3x target needs
a compiled march (a polar prefix-maximum pass in NumPy/OpenCV measured no cheaper: its
resampling and prefix maxima alone cost 3-4 ms a frame).
"""

from __future__ import annotations

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
TOL_M = 1.0  # a ray this close to the surface at a corner's hit altitude may settle there (m)
SETTLED_M = 0.05  # ... if after the secant step it is this close (m)
FLAT_M = 0.25  # a 2-pixel cell whose corners' hits differ by less is interpolated (m)
BLOCK_STEPS = (16, MAX_STEPS)  # rays are marched in blocks of up to these many steps
_MIN_DOWN = 1e-6
_COLS = 4096  # samples per remap row (cv2.remap wants fewer than 32767 rows and columns)
_NESTED = np.array([[0.5, 0.0, 0.0], [0.0, 0.5, 0.0]])  # dst (2i, 2j) <- src (i, j)
_CELL = np.array([[1, 2, 1, 2], [1, 1, 2, 2]])  # a stride-2 cell's pixels past its sample


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
    z_hit = np.empty(n, dtype=np.float32)
    found = np.empty(n, dtype=bool)
    if n == 0:
        return z_hit, found
    span = np.maximum(z_top - z_bottom, np.float32(0.0))
    steps = np.ceil(span * np.hypot(ax, ay))  # level px travelled over the range, at most
    block = np.searchsorted(np.array(BLOCK_STEPS, dtype=np.float32), steps)
    np.minimum(block, len(BLOCK_STEPS) - 1, out=block)
    ox, oy = np.float32(cx - window.x0), np.float32(cy - window.y0)
    args = (window.values, ox, oy, np.float32(cam_z))
    used = np.flatnonzero(np.bincount(block, minlength=len(BLOCK_STEPS)))
    if used.size == 1:  # one block: no gathering and scattering
        s = int(min(MAX_STEPS, max(1.0, float(steps.max()))))
        return _march_block(*args, ax, ay, z_top, span, s)
    for b in used.tolist():
        sel = np.flatnonzero(block == b)
        s = int(min(MAX_STEPS, max(1.0, float(steps[sel].max()))))
        z_hit[sel], found[sel] = _march_block(*args, ax[sel], ay[sel], z_top[sel], span[sel], s)
    return z_hit, found


def _march_block(
    values: Heights,
    ox: np.float32,
    oy: np.float32,
    cam: np.float32,
    ax: F32,
    ay: F32,
    z_top: F32,
    span: F32,
    steps: int,
) -> tuple[F32, npt.NDArray[np.bool_]]:
    """March rays in ``steps`` equal altitude steps each (see :func:`march`)."""
    n = ax.shape[0]
    # Samples as (steps + 1, n): NumPy's inner loops run over the rays (long), not the steps.
    t = (np.arange(steps + 1, dtype=np.float32) / np.float32(steps))[:, None]
    size = n * (steps + 1)
    buf_x, buf_y = _buffers(size)
    mx = buf_x[:size].reshape(steps + 1, n)
    my = buf_y[:size].reshape(steps + 1, n)
    d0 = cam - z_top  # depth below the camera at the top of the range
    np.multiply(t, span * ax, out=mx)
    mx += ox + d0 * ax
    np.multiply(t, span * ay, out=my)
    my += oy + d0 * ay
    h = _remap(values, buf_x, buf_y)[:size]
    z = (z_top - t * span).ravel()
    below = h >= z
    first = below.reshape(steps + 1, n).argmax(axis=0)
    at = first * n + np.arange(n)
    found = below[at]
    prev = np.where(first > 0, at - n, at)
    z_lo, z_hi = z[at], z[prev]  # first sample under the surface, last above
    f_lo, f_hi = z_lo - h[at], z_hi - h[prev]
    # Bisection between them, then the secant of (z - height) in the last bracket: exact on
    # a plane, and within 1/16 of a step anywhere.
    px0, py0 = ox + cam * ax, oy + cam * ay  # the ray at altitude z is at p0 - z * a
    bx, by = _buffers(n)
    qx, qy = bx[:n], by[:n]
    for _ in range(REFINE):
        zm = (z_hi + z_lo) * np.float32(0.5)
        np.subtract(px0, np.multiply(zm, ax, out=qx), out=qx)
        np.subtract(py0, np.multiply(zm, ay, out=qy), out=qy)
        fm = zm - _remap(values, bx, by)[:n]
        under = fm <= 0
        np.copyto(z_lo, zm, where=under)
        np.copyto(f_lo, fm, where=under)
        np.logical_not(under, out=under)
        np.copyto(z_hi, zm, where=under)
        np.copyto(f_hi, fm, where=under)
    denom = f_hi - f_lo
    ok = (first > 0) & (denom > 1e-6)
    safe = np.where(ok, denom, np.float32(1.0))
    z_lo = np.where(ok, z_lo + (z_hi - z_lo) * (-f_lo) / safe, z_lo)
    z_hit: F32 = np.where(found, z_lo, z_top - span).astype(np.float32)
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
    are the caller's to mask (sky). Samples sit at image points (STRIDE * j - PAD + 0.5,
    STRIDE * i - PAD + 0.5); each level halves the stride, interpolating midpoints and
    marching again only the cells whose corners' parallax differs by more than EDGE_PX.
    """
    st, pad = STRIDE, STRIDE // 2
    nx = -(-(width + pad) // st) + 1
    ny = -(-(height + pad) // st) + 1
    gu = np.arange(nx, dtype=np.float32) * st - (pad - 0.5)
    gv = np.arange(ny, dtype=np.float32) * st - (pad - 0.5)
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
            u = (ii * st).astype(np.float32) - np.float32(pad - 0.5)
            v = (jj * st).astype(np.float32) - np.float32(pad - 0.5)
            fine = ray_slopes(r, jac, level, u, v)
            z_fix, ok = settle(window, cx, cy, cam_z, fine.ax, fine.ay, corners)
            d = np.float32(cam_z) - z_fix
            grid[jj, ii] = np.stack(
                [
                    np.where(ok, ox + d * fine.ax, grid[jj, ii, 0]),
                    np.where(ok, oy + d * fine.ay, grid[jj, ii, 1]),
                    np.where(ok, z_fix, grid[jj, ii, 2]),
                    np.hypot(fine.ax, fine.ay),
                ],
                axis=-1,
            )
            stats["fixed_rays"] += float(jj.size)
        # Only cells inside an edge cell of the coarser level can be edges now.
        edge = _edges(grid, window.h_min) & np.repeat(np.repeat(edge, 2, 0), 2, 1)
    # Full resolution: bilinear from the stride-2 grid (sample (j, i) is image point
    # (2i - pad + 0.5, 2j - pad + 0.5): cv2.resize's x2 grid puts output pixel x - pad at
    # input x / 2 - 0.25), then every pixel of a remaining edge cell marched on its own.
    stats["rays_before_full"] = stats["fixed_rays"]
    coarse = np.ascontiguousarray(grid[:, :, :2])
    size = (2 * coarse.shape[1], 2 * coarse.shape[0])
    full: F32 = cv2.resize(coarse, size, interpolation=cv2.INTER_LINEAR)  # type: ignore[assignment]
    maps = full[pad : pad + height, pad : pad + width]  # a view: remap takes it
    zr = grid[:, :, 2]
    # A 2-pixel cell whose corners hit one height (within FLAT_M) holds no edge: interpolated.
    span = np.maximum(np.maximum(zr[:-1, :-1], zr[:-1, 1:]), np.maximum(zr[1:, :-1], zr[1:, 1:]))
    span -= np.minimum(np.minimum(zr[:-1, :-1], zr[:-1, 1:]), np.minimum(zr[1:, :-1], zr[1:, 1:]))
    edge &= span > np.float32(FLAT_M)
    if edge.any():
        ej, ei = np.nonzero(edge)
        # The cell's four pixels (none is a sample: they sit half a pixel off).
        py = (ej[:, None] * 2 - pad + _CELL[1]).ravel()
        px = (ei[:, None] * 2 - pad + _CELL[0]).ravel()
        corners = np.stack([zr[ej, ei], zr[ej, ei + 1], zr[ej + 1, ei], zr[ej + 1, ei + 1]])
        corners = np.repeat(corners, 4, axis=1)
        keep = (px >= 0) & (py >= 0) & (px < width) & (py < height)
        px, py, corners = px[keep], py[keep], corners[:, keep]
        fine = ray_slopes(r, jac, level, px.astype(np.float32), py.astype(np.float32))
        z_fix, ok = settle(window, cx, cy, cam_z, fine.ax, fine.ay, corners)
        d = np.float32(cam_z) - z_fix[ok]
        maps[py[ok], px[ok]] = np.stack([ox + d * fine.ax[ok], oy + d * fine.ay[ok]], axis=-1)
        stats["fixed_rays"] += float(px.size)
    return maps, stats


def settle(
    window: HeightWindow,
    cx: float,
    cy: float,
    cam_z: float,
    ax: F32,
    ay: F32,
    corners: F32,
) -> tuple[F32, npt.NDArray[np.bool_]]:
    """First surface point of rays inside a cell, from the altitudes its corners' rays hit.

    Each ray is tried at the corners' hit altitudes, highest first. At the first one where
    the ray is not above the surface (by more than TOL_M), a surface within TOL_M of the
    ray gives its hit by a secant step through "the height found there" (exact on a plane),
    kept if the ray is then within SETTLED_M of the surface. Rays under the surface there
    (a wall, or something no corner saw), above it at every corner altitude, or not settled
    are marched over the corners' range (:func:`march`). Returns (z_hit, found) as
    :func:`march` does.
    """
    m = ax.shape[0]
    if m == 0:
        return np.empty(0, dtype=np.float32), np.empty(0, dtype=bool)
    values, tol = window.values, np.float32(TOL_M)
    cand = _sorted_down(corners)  # (4, m), highest first
    cam = np.float32(cam_z)
    px0 = np.float32(cx - window.x0) + cam * ax  # the ray at altitude z is at p0 - z * a
    py0 = np.float32(cy - window.y0) + cam * ay
    size = cand.size
    bx, by = _buffers(size)
    np.subtract(px0, cand * ax, out=bx[:size].reshape(cand.shape))
    np.subtract(py0, cand * ay, out=by[:size].reshape(cand.shape))
    h = _remap(values, bx, by)[:size]
    f = cand.ravel() - h
    not_above = f <= tol
    na = not_above.reshape(cand.shape)
    k = np.where(na[0], 0, np.where(na[1], 1, np.where(na[2], 2, 3)))  # the first, or 3
    at = k * m + np.arange(m)
    f_k, z_k = f[at], cand.ravel()[at]
    on = not_above[at] & (f_k >= -tol)
    # Secant through (z_k, f_k) and the height found there (z_1 = h_k).
    z_1 = z_k - f_k
    qx, qy = bx[:m], by[:m]
    np.subtract(px0, z_1 * ax, out=qx)
    np.subtract(py0, z_1 * ay, out=qy)
    f_1 = z_1 - _remap(values, bx, by)[:m]
    denom = f_1 - f_k
    step = np.abs(denom) > 1e-6
    z_hit = np.where(step, z_1 - f_1 * (z_1 - z_k) / np.where(step, denom, 1.0), z_1)
    z_hit = z_hit.astype(np.float32)
    np.subtract(px0, z_hit * ax, out=qx)
    np.subtract(py0, z_hit * ay, out=qy)
    on &= np.abs(z_hit - _remap(values, bx, by)[:m]) <= np.float32(SETTLED_M)
    found = np.ones(m, dtype=bool)
    rest = np.flatnonzero(~on)
    if rest.size:
        # The ray was above the surface at the candidate before k (by more than TOL_M): the
        # march starts there (or 1 m over the highest corner) and ends at k (or under the
        # lowest corner, as in _range, where the ray was above at every one).
        top, bot = _range(corners[:, rest], window, cam_z)
        kr, cr = k[rest], cand[:, rest]
        cols = np.arange(rest.size)
        above_prev = np.where(kr > 0, cr[np.maximum(kr - 1, 0), cols], top)
        top = np.minimum(top, above_prev)
        bot = np.where(na[kr, rest], np.maximum(bot, cr[kr, cols] - tol), bot)
        z_hit[rest], found[rest] = march(window, cx, cy, cam_z, ax[rest], ay[rest], top, bot)
    return z_hit, found


def _sorted_down(corners: F32) -> F32:
    """The four rows sorted highest first, element by element (a sorting network: NumPy's
    sort along a short first axis costs far more)."""
    a, b, c, d = corners
    a, b = np.maximum(a, b), np.minimum(a, b)
    c, d = np.maximum(c, d), np.minimum(c, d)
    a, c = np.maximum(a, c), np.minimum(a, c)
    b, d = np.maximum(b, d), np.minimum(b, d)
    b, c = np.maximum(b, c), np.minimum(b, c)
    return np.stack([a, b, c, d])


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
    ny, nx = grid.shape[:2]
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    out: F32 = cv2.warpAffine(grid, _NESTED, (2 * nx - 1, 2 * ny - 1), flags=flags)  # type: ignore[assignment]
    return out


def _fresh_samples(edge: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Samples of the x2 grid that are new inside the given coarse cells."""
    cy, cx = edge.shape
    mask = np.zeros((2 * cy + 1, 2 * cx + 1), dtype=bool)
    j, i = np.nonzero(edge)
    for dj, di in ((1, 0), (0, 1), (1, 1), (2, 1), (1, 2)):
        mask[2 * j + dj, 2 * i + di] = True
    return mask


def _buffers(size: int) -> tuple[F32, F32]:
    """Two coordinate buffers holding ``size`` samples, shaped for one remap (zero tail)."""
    cols = size if size < 32767 else _COLS
    rows = -(-size // cols)
    bx = np.empty((rows, cols), dtype=np.float32)
    by = np.empty((rows, cols), dtype=np.float32)
    bx.ravel()[size:] = 0.0
    by.ravel()[size:] = 0.0
    return bx.ravel(), by.ravel()


def _remap(values: Heights, fx: F32, fy: F32) -> F32:
    """Bilinear heights at the level pixels of two buffers from :func:`_buffers`."""
    size = fx.shape[0]
    cols = size if size < 32767 else _COLS
    shape = (size // cols, cols)
    out = cv2.remap(values, fx.reshape(shape), fy.reshape(shape), interpolation=cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE)  # fmt: skip
    got: F32 = np.asarray(out, dtype=np.float32).ravel()
    return got


def _sample(values: Heights, mx: F32, my: F32) -> F32:
    """Bilinear heights at level pixels (mx, my) of one dimension (edges repeat outward)."""
    n = mx.shape[0]
    bx, by = _buffers(n)
    bx[:n] = mx
    by[:n] = my
    return _remap(values, bx, by)[:n]
