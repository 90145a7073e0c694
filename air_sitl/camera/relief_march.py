"""Compiled kernels of the relief renderer (numba): ray marching over a height field.

``relief`` holds the design; these are its loops, compiled once (about 6 s of CPU on the
first frame over relief; ``cache=True``: later processes load the machine code from
``__pycache__`` in well under a second) and run without the GIL. No
fastmath: every operation rounds as written, so the same inputs give the same bytes.

A ray is a straight line over the level-pixel grid of a height window: at altitude z it is
at (px0 - z * ax, py0 - z * ay). Heights are sampled bilinearly, edges repeated outward
(as ``cv2.remap`` with ``BORDER_REPLICATE``, without its 1/32-pixel rounding).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

F32 = npt.NDArray[np.float32]
_TILE_BITS = 3
TILE = 1 << _TILE_BITS  # level pixels per side of a max-height tile (overlapping by one)
MAX_FINE = 4096  # fine steps over a march's altitude range, at most
REFINE = 4  # bisection steps after the march, before the secant
TOL_M = 1.0  # a ray this close to the surface at a corner's hit altitude may settle there (m)
SETTLED_M = 0.05  # ... if after a secant step it is this close (m)
SECANT = 3  # secant steps at most (after the first, each staying within TOL_M)
EDGE_PX = 2.0  # a cell is re-solved where the parallax bends by more at a corner (px)
FLAT_M = 0.25  # a 2-pixel cell whose corners' hits differ by less is interpolated (m)
_MIN_DOWN = 1e-6


@compiled
def tile_max(values: F32) -> F32:
    """Highest height of each TILE x TILE tile, its far edges included (what a bilinear
    sample inside the tile can reach)."""
    h, w = values.shape
    th = max(1, -(-(h - 1) // TILE))
    tw = max(1, -(-(w - 1) // TILE))
    out = np.full((th, tw), -np.inf, dtype=np.float32)
    for ty in range(th):
        for y in range(ty * TILE, min(ty * TILE + TILE + 1, h)):
            for tx in range(tw):
                m = out[ty, tx]
                for x in range(tx * TILE, min(tx * TILE + TILE + 1, w)):
                    m = max(m, values[y, x])
                out[ty, tx] = m
    return out


@compiled
def _height(values: F32, x: float, y: float) -> float:
    """Bilinear height at level pixel (x, y) of the window, edges repeated outward."""
    h, w = values.shape
    x = min(max(x, 0.0), w - 1.0)
    y = min(max(y, 0.0), h - 1.0)
    x0, y0 = int(x), int(y)
    fx, fy = x - x0, y - y0
    x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
    top = float(values[y0, x0]) * (1.0 - fx) + float(values[y0, x1]) * fx
    bottom = float(values[y1, x0]) * (1.0 - fx) + float(values[y1, x1]) * fx
    return top * (1.0 - fy) + bottom * fy


@compiled
def _refine(
    values: F32, px0: float, py0: float, ax: float, ay: float,
    z_lo: float, f_lo: float, z_hi: float, f_hi: float,
) -> float:  # fmt: skip
    """First hit between z_lo (ray under the surface, f_lo <= 0) and z_hi (above): bisection,
    then the secant of (z - height) in the last bracket (exact on a plane)."""
    for _ in range(REFINE):
        zm = (z_hi + z_lo) * 0.5
        fm = zm - _height(values, px0 - zm * ax, py0 - zm * ay)
        if fm <= 0.0:
            z_lo, f_lo = zm, fm
        else:
            z_hi, f_hi = zm, fm
    denom = f_hi - f_lo
    if denom > 1e-6:
        return z_lo + (z_hi - z_lo) * (-f_lo) / denom
    return z_lo


@compiled
def march_ray(
    values: F32, tmax: F32, px0: float, py0: float, ax: float, ay: float,
    z_top: float, z_bot: float,
) -> tuple[float, bool]:  # fmt: skip
    """(altitude of the first surface point within [z_bot, z_top], found).

    A ray already under the surface at z_top hits there; one still above it at z_bot is not
    found (z_bot). Over a tile whose highest point is below the ray, the ray jumps to where
    it leaves the tile or comes down to that height; elsewhere it steps one level pixel (or
    1/MAX_FINE of the range) at a time; the first step under the surface is refined.
    """
    h, w = values.shape
    th, tw = tmax.shape
    z = z_top
    f = z - _height(values, px0 - z * ax, py0 - z * ay)
    if f <= 0.0:
        return z_top, True
    span = z_top - z_bot
    if span <= 0.0:
        return z_top, False
    slope = math.sqrt(ax * ax + ay * ay)
    dz = span / MAX_FINE
    if slope * dz < 1.0:
        dz = span if slope * span <= 1.0 else 1.0 / slope
    inv_x = 1.0 / ax if ax != 0.0 else 0.0
    inv_y = 1.0 / ay if ay != 0.0 else 0.0
    while True:
        x, y = px0 - z * ax, py0 - z * ay
        zn = z
        if 0.0 <= x <= w - 1.0 and 0.0 <= y <= h - 1.0:
            tx, ty = min(int(x) >> _TILE_BITS, tw - 1), min(int(y) >> _TILE_BITS, th - 1)
            top = tmax[ty, tx]  # the ray cannot meet this tile's surface above its top
            if z > top:  # jump to where the ray leaves the tile, or comes down to its top
                zn = top
                if ax > 0.0:
                    zn = max(zn, z - ((tx + 1) * TILE - x) * inv_x)
                elif ax < 0.0:
                    zn = max(zn, z - (x - tx * TILE) * -inv_x)
                if ay > 0.0:
                    zn = max(zn, z - ((ty + 1) * TILE - y) * inv_y)
                elif ay < 0.0:
                    zn = max(zn, z - (y - ty * TILE) * -inv_y)
        if zn >= z:  # near the surface (or off the window): one fine step
            zn = z - dz
        zn = max(zn, z_bot)
        fn = zn - _height(values, px0 - zn * ax, py0 - zn * ay)
        if fn <= 0.0:
            return _refine(values, px0, py0, ax, ay, zn, fn, z, f), True
        if zn <= z_bot:
            return z_bot, False
        z, f = zn, fn


@compiled
def settle_ray(
    values: F32, tmax: F32, px0: float, py0: float, ax: float, ay: float,
    corners: npt.NDArray[np.float64], cam_z: float, h_min: float, h_max: float,
) -> tuple[float, bool]:  # fmt: skip
    """First surface point of a ray inside a cell, from the altitudes its corners' rays hit.

    The ray is tried at the corners' hit altitudes, highest first. At the first one where
    it is not above the surface (by more than TOL_M), a surface within TOL_M of the ray
    gives the hit by secant steps through "the height found there" (exact on a plane; up
    to SECANT on a curved surface), kept once the ray is within SETTLED_M of the surface.
    Rays under the surface there
    (a wall, or something no corner saw), above it at every corner altitude, or not settled
    are marched (:func:`march_ray`) from the candidate above (or 1 m over the highest
    corner) down to that one (or 0.25 m under the lowest corner).
    """
    a, b, c, d = corners[0], corners[1], corners[2], corners[3]
    a, b = max(a, b), min(a, b)  # a sorting network: highest first
    c, d = max(c, d), min(c, d)
    a, c = max(a, c), min(a, c)
    b, d = max(b, d), min(b, d)
    b, c = max(b, c), min(b, c)
    cand = (a, b, c, d)
    k, f_k, not_above = 3, 0.0, False
    for i in range(4):
        f_k = cand[i] - _height(values, px0 - cand[i] * ax, py0 - cand[i] * ay)
        if f_k <= TOL_M:
            k, not_above = i, True
            break
    z_k = cand[k]
    if not_above and f_k >= -TOL_M:
        z_0, f_0 = z_k, f_k
        z_1 = z_k - f_k  # the height found there
        f_1 = z_1 - _height(values, px0 - z_1 * ax, py0 - z_1 * ay)
        for step in range(SECANT):
            denom = f_1 - f_0
            z_2 = z_1 - f_1 * (z_1 - z_0) / denom if abs(denom) > 1e-6 else z_1
            if step > 0 and abs(z_2 - z_k) > TOL_M:
                break  # wandering off: marched instead
            f_2 = z_2 - _height(values, px0 - z_2 * ax, py0 - z_2 * ay)
            if abs(f_2) <= SETTLED_M:
                return z_2, True
            z_0, f_0, z_1, f_1 = z_1, f_1, z_2, f_2
    top = min(a + 1.0, h_max, cam_z)
    bot = max(d - 0.25, h_min)
    if k > 0:
        top = min(top, cand[k - 1])
    if not_above:
        bot = max(bot, z_k - TOL_M)
    z_hit, found = march_ray(values, tmax, px0, py0, ax, ay, top, bot)
    return z_hit, found


@compiled
def _ray(
    r: npt.NDArray[np.float64], jac: npt.NDArray[np.float64], s: float, u: float, v: float
) -> tuple[float, float]:
    """Level pixels travelled per metre of descent by the ray of image point (u, v) (zero
    for a ray that never descends)."""
    dd = r[6] * u + r[7] * v + r[8]
    if dd <= _MIN_DOWN:
        return 0.0, 0.0
    dn = r[0] * u + r[1] * v + r[2]
    de = r[3] * u + r[4] * v + r[5]
    inv = 1.0 / (s * dd)
    return (jac[0] * dn + jac[1] * de) * inv, (jac[2] * dn + jac[3] * de) * inv


@compiled
def _edges(grid: F32, h_min: float, parent: npt.NDArray[np.bool_]) -> npt.NDArray[np.bool_]:
    """Cells next to a sample where the parallax (pixels of lean) bends by more than
    EDGE_PX: its second difference along rows and columns, zero on a plane or a steady
    slope (where interpolation is exact), large at steps and on rough surfaces. Only cells
    inside an edge cell of the coarser ``parent`` grid (cell (j, i) in (j // 2, i // 2))
    can be edges; an empty ``parent`` means every cell can."""
    ny, nx = grid.shape[1:]
    par = np.empty((ny, nx), dtype=np.float32)
    base = np.float32(h_min)
    for j in range(ny):
        for i in range(nx):
            par[j, i] = (grid[2, j, i] - base) * grid[3, j, i]
    hot = np.zeros((ny, nx), dtype=np.bool_)
    lim, two = np.float32(EDGE_PX), np.float32(2.0)
    for j in range(ny):
        for i in range(1, nx - 1):
            hot[j, i] = abs(par[j, i - 1] - two * par[j, i] + par[j, i + 1]) > lim
    for j in range(1, ny - 1):
        for i in range(nx):
            hot[j, i] |= abs(par[j - 1, i] - two * par[j, i] + par[j + 1, i]) > lim
    edge = np.empty((ny - 1, nx - 1), dtype=np.bool_)
    whole = parent.size == 0
    for j in range(ny - 1):
        for i in range(nx - 1):
            edge[j, i] = (hot[j, i] or hot[j, i + 1] or hot[j + 1, i] or hot[j + 1, i + 1]) and (
                whole or parent[j // 2, i // 2]
            )
    return edge


@compiled
def _upsample(grid: F32) -> F32:
    """Nested x2 upsampling of each plane: old samples kept, midpoints and centres averaged
    (bilinear)."""
    nc, ny, nx = grid.shape
    out = np.empty((nc, 2 * ny - 1, 2 * nx - 1), dtype=np.float32)
    half = np.float32(0.5)
    for c in range(nc):
        for j in range(ny):
            for i in range(nx - 1):
                out[c, 2 * j, 2 * i] = grid[c, j, i]
                out[c, 2 * j, 2 * i + 1] = (grid[c, j, i] + grid[c, j, i + 1]) * half
            out[c, 2 * j, 2 * nx - 2] = grid[c, j, nx - 1]
        for j in range(ny - 1):
            for i in range(2 * nx - 1):
                out[c, 2 * j + 1, i] = (out[c, 2 * j, i] + out[c, 2 * j + 2, i]) * half
    return out


@compiled
def sample_grid(
    values: F32, tmax: F32, r: npt.NDArray[np.float64], jac: npt.NDArray[np.float64],
    s: float, ox: float, oy: float, cam_z: float, h_min: float, h_max: float,
    width: int, height: int, stride: int,
) -> tuple[F32, npt.NDArray[np.bool_], int, int]:  # fmt: skip
    """The stride-2 grid, as planes (map x, map y, hit altitude, parallax rate), and its edge
    cells.

    Sample (j, i) of a stride-``st`` grid is image point (st * i - pad + 0.5, st * j - pad +
    0.5), pad = stride / 2. The coarse grid is marched; each halving of the stride
    interpolates the new samples and solves again (:func:`settle_ray`) those inside edge
    cells. Returns (grid, edge cells, coarse rays, solved rays).
    """
    pad = stride // 2
    nx = -(-(width + pad) // stride) + 1
    ny = -(-(height + pad) // stride) + 1
    grid = np.empty((4, ny, nx), dtype=np.float32)  # planes: map x, map y, z, px per m
    z_top = min(h_max, cam_z)
    for j in range(ny):
        for i in range(nx):
            ax, ay = _ray(r, jac, s, i * stride - (pad - 0.5), j * stride - (pad - 0.5))
            px0, py0 = ox + cam_z * ax, oy + cam_z * ay
            z, _ = march_ray(values, tmax, px0, py0, ax, ay, z_top, h_min)
            grid[0, j, i], grid[1, j, i] = px0 - z * ax, py0 - z * ay
            grid[2, j, i], grid[3, j, i] = z, math.sqrt(ax * ax + ay * ay)
    edge = _edges(grid, h_min, np.zeros((0, 0), dtype=np.bool_))
    st, solved = stride, 0
    corners = np.empty(4, dtype=np.float64)
    fresh_at = ((1, 0), (0, 1), (1, 1), (2, 1), (1, 2))  # new samples around a coarse cell
    while st > 2:
        grid = _upsample(grid)
        st //= 2
        gy, gx = grid.shape[1:]
        fresh = np.zeros((gy, gx), dtype=np.bool_)
        for j in range(edge.shape[0]):
            for i in range(edge.shape[1]):
                if edge[j, i]:
                    for dj, di in fresh_at:
                        fresh[2 * j + dj, 2 * i + di] = True
        for jj in range(gy):
            for ii in range(gx):
                if not fresh[jj, ii]:
                    continue
                # The corners of the coarse cell below and right (old samples: even indices).
                pj, pi = (jj // 2) * 2, (ii // 2) * 2
                pj1, pi1 = min(pj + 2, gy - 1), min(pi + 2, gx - 1)
                corners[0], corners[1] = grid[2, pj, pi], grid[2, pj, pi1]
                corners[2], corners[3] = grid[2, pj1, pi], grid[2, pj1, pi1]
                if corners.max() - corners.min() <= FLAT_M:
                    continue
                ax, ay = _ray(r, jac, s, ii * st - (pad - 0.5), jj * st - (pad - 0.5))
                px0, py0 = ox + cam_z * ax, oy + cam_z * ay
                z, ok = settle_ray(values, tmax, px0, py0, ax, ay, corners, cam_z, h_min, h_max)
                if ok:
                    grid[0, jj, ii], grid[1, jj, ii] = px0 - z * ax, py0 - z * ay
                    grid[2, jj, ii] = z
                grid[3, jj, ii] = math.sqrt(ax * ax + ay * ay)
                solved += 1
        edge = _edges(grid, h_min, edge)  # only inside the coarser level's edge cells
    return grid, edge, ny * nx, solved


@compiled
def strip_bounds(grid: F32, pad: int, height: int, rows: int) -> F32:
    """(x min, y min, x max, y max) of the map points of each strip of ``rows`` image rows
    (rows [k * rows, (k + 1) * rows)), from the stride-2 samples its pixels interpolate
    (a bilinear value lies between its samples'; cv2.resize's x2 puts output row Y at input
    row Y / 2 - 0.25), a row of samples to spare on each side."""
    ny, nx = grid.shape[1:]
    count = -(-height // rows)
    out = np.empty((count, 4), dtype=np.float32)
    for k in range(count):
        v0, v1 = k * rows, min(height, (k + 1) * rows)
        j0 = max(0, (v0 + pad) // 2 - 2)
        j1 = min(ny - 1, (v1 - 1 + pad) // 2 + 2)
        x_lo, y_lo = grid[0, j0, 0], grid[1, j0, 0]
        x_hi, y_hi = x_lo, y_lo
        for j in range(j0, j1 + 1):
            for i in range(nx):
                x, y = grid[0, j, i], grid[1, j, i]
                x_lo, x_hi = min(x_lo, x), max(x_hi, x)
                y_lo, y_hi = min(y_lo, y), max(y_hi, y)
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = x_lo, y_lo, x_hi, y_hi
    return out


@compiled
def solve_edge_pixels(
    full: F32, grid: F32, edge: npt.NDArray[np.bool_], values: F32, tmax: F32,
    r: npt.NDArray[np.float64], jac: npt.NDArray[np.float64], s: float, ox: float,
    oy: float, cam_z: float, h_min: float, h_max: float, pad: int, width: int, height: int,
    bounds: F32, rows: int,
) -> int:  # fmt: skip
    """Every pixel of a stride-2 edge cell whose corners' hits differ by more than FLAT_M,
    solved on its own into ``full`` (pixel (px, py) at full[py + pad, px + pad]), widening
    its strip's ``bounds`` (:func:`strip_bounds`); the number of pixels solved."""
    corners = np.empty(4, dtype=np.float64)
    solved = 0
    for j in range(edge.shape[0]):
        for i in range(edge.shape[1]):
            if not edge[j, i]:
                continue
            corners[0], corners[1] = grid[2, j, i], grid[2, j, i + 1]
            corners[2], corners[3] = grid[2, j + 1, i], grid[2, j + 1, i + 1]
            if corners.max() - corners.min() <= FLAT_M:
                continue
            # The cell's four pixels (none is a sample: they sit half a pixel off).
            for dy in (1, 2):
                py = 2 * j - pad + dy
                if py < 0 or py >= height:
                    continue
                for dx in (1, 2):
                    px = 2 * i - pad + dx
                    if px < 0 or px >= width:
                        continue
                    ax, ay = _ray(r, jac, s, float(px), float(py))
                    px0, py0 = ox + cam_z * ax, oy + cam_z * ay
                    z, ok = settle_ray(values, tmax, px0, py0, ax, ay, corners, cam_z, h_min, h_max)
                    if ok:
                        x, y = np.float32(px0 - z * ax), np.float32(py0 - z * ay)
                        full[py + pad, px + pad, 0], full[py + pad, px + pad, 1] = x, y
                        b = bounds[py // rows]
                        b[0], b[1] = min(b[0], x), min(b[1], y)
                        b[2], b[3] = max(b[2], x), max(b[3], y)
                    solved += 1
    return solved
