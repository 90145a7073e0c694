"""Compiled kernels of the relief renderer (numba): exact first hits of rays on a height field.

``relief`` holds the design; these are its loops, compiled once (``air_sitl.compiled``: built
ahead of time, seconds of CPU after an install; later processes load the machine code in
milliseconds) and run without the GIL. No fastmath: every operation rounds as written, so
the same inputs give the same bytes.

A ray is a straight line over the level-pixel grid of a height window: at altitude z it is
at (px0 - z * ax, py0 - z * ay). The surface is the bilinear interpolation of the window's
posts (heights at level-pixel centres), edges repeated outward (as ``cv2.remap`` with
``BORDER_REPLICATE``, without its 1/32-pixel rounding). Cell (i, j) is the square between
posts (i, j) and (i + 1, j + 1); inside it the surface is h00 + b u + c v + d u v.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled, compiled_inline

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]
_TILE_BITS = 3
TILE = 1 << _TILE_BITS  # cells per side of a max-height tile
BLOCK = 16  # image pixels per side of a block whose rays skip the empty space above together
MAX_FINE = 4096  # fine steps over a march's altitude range, at most (rays leaving the window)
REFINE = 4  # bisection steps after a fine march, before the secant
_MIN_DOWN = 1e-6
_BIG = 1e30
_TINY = 1e-12  # level pixels per metre: the slope a walk takes for a zero one
_MINUS_ONE = np.uint64(0xFFFF_FFFF_FFFF_FFFF)  # a step back, as an unsigned cell index
# The exported kernels' signatures (numba's notation, air_sitl.compiled): f4[:, ::1] a
# contiguous float32 image (heights, tops), f8 float64, i8 int64, b1 bool.
_TOPS = "f4[:, ::1](f4[:, ::1])"


@compiled(_TOPS)
def tile_max(values: F32) -> F32:
    """Highest post of each TILE x TILE-cell tile, its far edges included (the highest
    point the bilinear surface reaches over the tile)."""
    n = TILE
    h, w = values.shape
    th = max(1, -(-(h - 1) // n))
    tw = max(1, -(-(w - 1) // n))
    out = np.full((th, tw), -np.inf, dtype=np.float32)
    for ty in range(th):
        for y in range(ty * n, min(ty * n + n + 1, h)):
            for tx in range(tw):
                m = out[ty, tx]
                for x in range(tx * n, min(tx * n + n + 1, w)):
                    m = max(m, values[y, x])
                out[ty, tx] = m
    return out


@compiled(_TOPS)
def cell_max(values: F32) -> F32:
    """Highest of the four posts of each cell (the highest point of its bilinear patch)."""
    h, w = values.shape
    out = np.empty((max(1, h - 1), max(1, w - 1)), dtype=np.float32)
    if h < 2 or w < 2:
        out[:] = values.max()
        return out
    for y in range(h - 1):
        for x in range(w - 1):
            out[y, x] = max(values[y, x], values[y, x + 1], values[y + 1, x], values[y + 1, x + 1])
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


@compiled("Tuple((f8, b1))(f4[:, ::1], f4[:, ::1], f8, f8, f8, f8, f8, f8)")
def march_ray(
    values: F32, tmax: F32, px0: float, py0: float, ax: float, ay: float,
    z_top: float, z_bot: float,
) -> tuple[float, bool]:  # fmt: skip
    """(altitude of the first surface point within [z_bot, z_top], found) by fine steps: for
    rays that leave the window (where the surface is its edges repeated outward), which
    :func:`first_hit` hands over.

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


@compiled_inline
def _patch_hit(
    values: F32, i: np.uint64, j: np.uint64, x: float, y: float, z: float, ax: float, ay: float,
    span: float,
) -> tuple[bool, float]:  # fmt: skip
    """(whether the ray meets cell (i, j)'s bilinear patch within a descent of ``span`` from
    altitude z at level pixel (x, y), the descent (0 .. span) to the first point where it is
    not above the patch).

    Along the ray, g(t) = z - t - height is a quadratic in the descent t (the patch is
    bilinear, the ray straight): ga + gb t + gc t^2 with ga = g(0). It has a root in
    [0, span] where it is not above at the end, or where it is convex and dips below
    between; only then is the root solved (a square root and a division, in the form that
    does not cancel). The flag is decided before the root, so the walk's branch on it
    does not wait for the square root and the division.
    """
    one = np.uint64(1)
    h00 = float(values[j, i])
    hx = float(values[j, i + one]) - h00
    hy = float(values[j + one, i]) - h00
    hxy = float(values[j + one, i + one]) - h00 - hx - hy
    u, v = x - float(i), y - float(j)
    ga = z - (h00 + hx * u + hy * v + hxy * u * v)
    if ga <= 0.0:
        return True, 0.0
    gb = -1.0 - hx * ax - hy * ay - hxy * (u * ay + v * ax)
    gc = -hxy * ax * ay
    if ga + span * (gb + span * gc) > 0.0 and (
        gc <= 0.0 or gb >= 0.0 or -gb >= 2.0 * gc * span or 4.0 * ga * gc > gb * gb
    ):
        return False, 0.0  # above at both ends and nowhere below between
    root = math.sqrt(max(gb * gb - 4.0 * gc * ga, 0.0))
    # The first root on the way down: with gb < 0 the smaller positive one; else g is
    # concave (gc < 0) and it is the only positive one.
    t = 2.0 * ga / (root - gb) if gb < 0.0 else (-gb - root) / (2.0 * gc)
    return True, min(max(t, 0.0), span)


@compiled_inline
def walk_rays(
    values: F32, cmax: F32, tmax: F32, ax: F64, ay: F64, n: int, ox: float, oy: float,
    cam_z: float, z_top: float, z_bot: float, z_out: F64, scratch: F64, cells: I64,
) -> None:  # fmt: skip
    """The altitude of the first surface point of rays 0 .. n-1 within [z_bot, z_top] into
    ``z_out`` (z_bot where a ray meets none); ray k at altitude z is at level pixel
    (ox + (cam_z - z) ax[k], oy + (cam_z - z) ay[k]). ``scratch`` (6, n or more) and
    ``cells`` (3, n or more) hold the walks' starts; then ``cells[2]`` is 1 where the ray
    met the surface, 0 where not.

    Exact: each ray walks the cells it crosses in order (a grid walk over the level-pixel
    grid), passes every cell whose highest post is below the ray where it leaves the cell,
    and solves the quadratic of the cells it may meet (:func:`_patch_hit`). A ray already
    under the surface at z_top hits there. A ray that leaves the window between z_top and
    z_bot is marched by fine steps (:func:`march_ray`).

    In two passes: first every ray's start (where it enters its first cell, its steps),
    in a loop without branches the compiler turns into vector code; then the walks, each
    starting from numbers already in the core's cache: a walk is a chain of dependent
    steps, and a mispredicted branch at its end stalls the next walk until its start is
    computed, so the less a walk has to compute before its first step, the faster.

    The walk divides nothing: descents t are kept multiplied by |ax| |ay| (the next
    boundary across x is at t |ax| |ay| = (distance in x) |ay|), so the comparisons of a
    step are products; a zero slope is taken as 1e-12 level pixels per metre.
    """
    h, w = values.shape
    ci, cj = w - 2, h - 2  # the last cell in each direction
    last_i, last_j = np.uint64(max(ci, 0)), np.uint64(max(cj, 0))
    span = z_top - z_bot
    hi_x, hi_y = w - 1.0, h - 1.0
    for k in range(n):  # the starts (vector code: no branches, only selects)
        a, b = ax[k], ay[k]
        px0, py0 = ox + cam_z * a, oy + cam_z * b
        xa, ya = px0 - z_top * a, py0 - z_top * b
        xb, yb = px0 - z_bot * a, py0 - z_bot * b
        inside = (
            (xa >= 0.0) & (xa <= hi_x) & (ya >= 0.0) & (ya <= hi_y)
            & (xb >= 0.0) & (xb <= hi_x) & (yb >= 0.0) & (yb <= hi_y)
        )  # fmt: skip
        i = min(int(min(max(xa, 0.0), hi_x)), ci)
        j = min(int(min(max(ya, 0.0), hi_y)), cj)
        sx, sy = max(abs(a), _TINY), max(abs(b), _TINY)
        scale = sx * sy
        scratch[0, k] = (i + 1 - xa) * sy if a >= 0.0 else (xa - i) * sy  # next x boundary
        scratch[1, k] = (j + 1 - ya) * sx if b >= 0.0 else (ya - j) * sx  # next y boundary
        scratch[2, k] = scale
        scratch[3, k] = 1.0 / scale
        scratch[4, k] = xa
        scratch[5, k] = ya
        cells[0, k], cells[1, k], cells[2, k] = i, j, inside
    for k in range(n):  # the walks
        a, b = ax[k], ay[k]
        if cells[2, k] == 0 or w < 2 or h < 2:
            z, found = march_ray(values, tmax, ox + cam_z * a, oy + cam_z * b, a, b, z_top,
                                 z_bot)  # fmt: skip
            z_out[k], cells[2, k] = z, found
            continue
        z_out[k], cells[2, k] = z_bot, 0
        if span < 0.0:
            z_out[k] = z_top
            continue
        next_x, next_y = scratch[0, k], scratch[1, k]
        scale, inv_scale = scratch[2, k], scratch[3, k]
        # Cell indices unsigned: a step back from 0 wraps past the last cell (one test for
        # both ends), and indexing needs no test for negative indices (about 8 % faster).
        xa, ya = scratch[4, k], scratch[5, k]
        i, j = np.uint64(cells[0, k]), np.uint64(cells[1, k])
        sx, sy = max(abs(a), _TINY), max(abs(b), _TINY)
        step_i = np.uint64(1) if a >= 0.0 else _MINUS_ONE
        step_j = np.uint64(1) if b >= 0.0 else _MINUS_ONE
        end = span * scale
        here = 0.0  # the descent at the cell's entry, times scale
        while True:
            out = min(next_x, next_y, end)  # ... at its exit
            if out >= (z_top - cmax[j, i]) * scale:  # not above the cell's top at the exit
                t = here * inv_scale
                hit, root = _patch_hit(values, i, j, xa + a * t, ya + b * t, z_top - t, a, b,
                                       (out - here) * inv_scale)  # fmt: skip
                if hit:
                    z_out[k], cells[2, k] = z_top - t - root, 1
                    break
            if out >= end:
                break
            here = out
            if next_x < next_y:
                i += step_i
                next_x += sy
            else:
                j += step_j
                next_y += sx
            if i > last_i or j > last_j:
                break  # (only by rounding at the window's edge)


@compiled("Tuple((f8, b1))(f4[:, ::1], f4[:, ::1], f4[:, ::1], f8, f8, f8, f8, f8, f8)")
def first_hit(
    values: F32, cmax: F32, tmax: F32, px0: float, py0: float, ax: float, ay: float,
    z_top: float, z_bot: float,
) -> tuple[float, bool]:  # fmt: skip
    """(altitude of the first point of the ray on the surface within [z_bot, z_top], found)
    of one ray, at level pixel (px0 - z ax, py0 - z ay) at altitude z (:func:`walk_rays`)."""
    z, cells = np.empty(1), np.empty((3, 1), dtype=np.int64)
    walk_rays(values, cmax, tmax, np.full(1, ax), np.full(1, ay), 1, px0, py0, 0.0, z_top,
              z_bot, z, np.empty((6, 1)), cells)  # fmt: skip
    return z[0], cells[2, 0] != 0


@compiled_inline
def _ray(r: F64, jac: F64, s: float, u: float, v: float) -> tuple[float, float]:
    """Level pixels travelled per metre of descent by the ray of image point (u, v) (zero
    for a ray that never descends)."""
    dd = r[6] * u + r[7] * v + r[8]
    dn = r[0] * u + r[1] * v + r[2]
    de = r[3] * u + r[4] * v + r[5]
    inv = 1.0 / (s * dd) if dd > _MIN_DOWN else 0.0  # a select: loops of rays vectorise
    return (jac[0] * dn + jac[1] * de) * inv, (jac[2] * dn + jac[3] * de) * inv


@compiled_inline
def _block_top(
    tmax: F32, r: F64, jac: F64, s: float, ox: float, oy: float, cam_z: float,
    u0: int, v0: int, u1: int, v1: int, z_top: float, z_bot: float,
) -> float:  # fmt: skip
    """An altitude above which no ray of image pixels [u0, u1] x [v0, v1] meets the surface.

    At one altitude the rays of a block lie inside the quadrilateral of its four corner rays
    (a homography of the image block), so between two altitudes inside the bounding box of
    the eight corner points: the block descends while the tiles under that box are all
    lower than the bottom of the step, then to their top, and stops there.
    """
    th, tw = tmax.shape
    for u, v in ((u0, v0), (u1, v0), (u0, v1), (u1, v1)):
        if r[6] * u + r[7] * v + r[8] <= _MIN_DOWN:
            return z_top  # a ray of the block misses the ground: each ray on its own
    ax0, ay0 = _ray(r, jac, s, float(u0), float(v0))
    ax1, ay1 = _ray(r, jac, s, float(u1), float(v0))
    ax2, ay2 = _ray(r, jac, s, float(u0), float(v1))
    ax3, ay3 = _ray(r, jac, s, float(u1), float(v1))
    # The box of the corners' offsets from the camera, per metre of descent.
    lo_x, hi_x = min(ax0, ax1, ax2, ax3), max(ax0, ax1, ax2, ax3)
    lo_y, hi_y = min(ay0, ay1, ay2, ay3), max(ay0, ay1, ay2, ay3)
    slope = max(abs(lo_x), abs(hi_x), abs(lo_y), abs(hi_y))
    dz = TILE / slope if slope > 0.0 else z_top - z_bot
    z = z_top
    while z > z_bot:
        zn = max(z - dz, z_bot)
        d0, d1 = cam_z - z, cam_z - zn  # descents from the camera, d0 < d1
        x_lo = ox + min(d0 * lo_x, d1 * lo_x)
        x_hi = ox + max(d0 * hi_x, d1 * hi_x)
        y_lo = oy + min(d0 * lo_y, d1 * lo_y)
        y_hi = oy + max(d0 * hi_y, d1 * hi_y)
        tx0 = min(max(math.floor(x_lo) >> _TILE_BITS, 0), tw - 1)
        tx1 = min(max(math.floor(x_hi) >> _TILE_BITS, 0), tw - 1)
        ty0 = min(max(math.floor(y_lo) >> _TILE_BITS, 0), th - 1)
        ty1 = min(max(math.floor(y_hi) >> _TILE_BITS, 0), th - 1)
        top = -_BIG
        for ty in range(ty0, ty1 + 1):
            for tx in range(tx0, tx1 + 1):
                top = max(top, float(tmax[ty, tx]))
        if top < zn:
            z = zn
        elif top < z:
            z = top
        else:
            break
    return z


@compiled(
    "void(f4[:, ::1], f4[:, ::1], f4[:, ::1], f8[::1], f8[::1], f8, f8, f8, f8, f8, f8, i8, i8, "
    "i8, f4[:, :, ::1], f4[:, ::1])"
)
def hit_maps(
    values: F32, cmax: F32, tmax: F32, r: F64, jac: F64, s: float, ox: float, oy: float,
    cam_z: float, h_min: float, h_max: float, width: int, height: int, rows: int,
    maps: F32, bounds: F32,
) -> None:  # fmt: skip
    """Every pixel's first surface point into ``maps`` ((height, width, 2) window level
    pixels) and the (x min, y min, x max, y max) of each strip of ``rows`` image rows into
    ``bounds``. Blocks of BLOCK x BLOCK pixels start their rays together below the empty
    space above them (:func:`_block_top`); each ray then finds its own first hit
    (:func:`walk_rays`)."""
    for k in range(bounds.shape[0]):
        bounds[k, 0] = bounds[k, 1] = np.float32(np.inf)
        bounds[k, 2] = bounds[k, 3] = np.float32(-np.inf)
    z_top = min(h_max, cam_z)
    n = BLOCK * BLOCK
    ax, ay, z = np.empty(n), np.empty(n), np.empty(n)
    scratch, cells = np.empty((6, n)), np.empty((3, n), dtype=np.int64)
    for v0 in range(0, height, BLOCK):
        v1 = min(v0 + BLOCK, height) - 1
        for u0 in range(0, width, BLOCK):
            u1 = min(u0 + BLOCK, width) - 1
            bw = u1 - u0 + 1
            top = _block_top(tmax, r, jac, s, ox, oy, cam_z, u0, v0, u1, v1, z_top, h_min)
            for py in range(v0, v1 + 1):  # the block's rays (vector code)
                for px in range(u0, u1 + 1):
                    q = (py - v0) * bw + px - u0
                    ax[q], ay[q] = _ray(r, jac, s, float(px), float(py))
            walk_rays(values, cmax, tmax, ax, ay, (v1 - v0 + 1) * bw, ox, oy, cam_z, top,
                      h_min, z, scratch, cells)  # fmt: skip
            for py in range(v0, v1 + 1):
                k = py // rows
                x_lo, y_lo = bounds[k, 0], bounds[k, 1]
                x_hi, y_hi = bounds[k, 2], bounds[k, 3]
                for px in range(u0, u1 + 1):
                    q = (py - v0) * bw + px - u0
                    px0, py0 = ox + cam_z * ax[q], oy + cam_z * ay[q]
                    x, y = np.float32(px0 - z[q] * ax[q]), np.float32(py0 - z[q] * ay[q])
                    maps[py, px, 0], maps[py, px, 1] = x, y
                    x_lo, y_lo = min(x_lo, x), min(y_lo, y)
                    x_hi, y_hi = max(x_hi, x), max(y_hi, y)
                bounds[k, 0], bounds[k, 1] = x_lo, y_lo
                bounds[k, 2], bounds[k, 3] = x_hi, y_hi
