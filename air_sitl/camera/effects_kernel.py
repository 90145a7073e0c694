"""The compiled loops of the camera effects' geometry (numba, ``air_sitl.compiled``): the blur's
paths and the haze on the coarse grid, the rows' homographies through the exposure's poses,
and the map of a frame's pixels (each row through its own homography, at the pinhole points of
the lens). The sampling is OpenCV's ``remap`` (``effects_frame``); the passes over the sampled
pixels (the motion blur, the light) are :mod:`air_sitl.camera.effects_pixels_kernel`.

The loops are written so that LLVM vectorizes them (rows as flat arrays, no branch per
pixel): without ``fastmath`` each operation rounds as written, so vectorizing changes no byte.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.camera.homography import MIN_DOWN
from air_sitl.compiled import compiled

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
I64 = npt.NDArray[np.int64]

MISS = -1e7  # a map coordinate far off any mosaic: the fill colour
# The kernels' signatures (numba's notation, air_sitl.compiled): f8[:, :] a float64 image,
# a view (the pinhole points of the frame's cut), f4[:, :, ::1] a contiguous float32 one.


@compiled
def _gradient(f: F64, x: F64, axis: int, out: F64) -> None:
    """``numpy.gradient(f, x, axis=axis)`` of a 2-D grid into ``out`` (second order inside,
    first order at the edges; uniform spacing as NumPy finds it: all steps equal)."""
    n = f.shape[axis]
    uniform = True
    for i in range(1, n - 1):
        if x[i + 1] - x[i] != x[1] - x[0]:
            uniform = False
    other = f.shape[1 - axis]
    for j in range(other):
        for i in range(n):
            a0 = f[i, j] if axis == 0 else f[j, i]
            if i == 0 or i == n - 1:
                lo, hi = (0, 1) if i == 0 else (n - 2, n - 1)
                flo = f[lo, j] if axis == 0 else f[j, lo]
                fhi = f[hi, j] if axis == 0 else f[j, hi]
                g = (fhi - flo) / (x[hi] - x[lo])
            else:
                fm = f[i - 1, j] if axis == 0 else f[j, i - 1]
                fp = f[i + 1, j] if axis == 0 else f[j, i + 1]
                if uniform:
                    g = (fp - fm) / (2.0 * (x[1] - x[0]))
                else:
                    d1, d2 = x[i] - x[i - 1], x[i + 1] - x[i]
                    g = (-d2 / (d1 * (d1 + d2)) * fm + (d2 - d1) / (d1 * d2) * a0
                         + d1 / (d2 * (d1 + d2)) * fp)  # fmt: skip
            if axis == 0:
                out[i, j] = g
            else:
                out[j, i] = g


@compiled
def _project(h: F64, gu: F64, gv: F64, x: F64, y: F64, hit: npt.NDArray[np.bool_]) -> None:
    """Map points of the grid (gu, gv) under per-grid-row homographies ``h`` (rows, 9) into
    (x, y), and whether each ray meets the ground (``hit``; where not, x = y = 0)."""
    rows, cols = gu.shape
    for i in range(rows):
        for j in range(cols):
            u, v = gu[i, j], gv[i, j]
            w = h[i, 6] * u + h[i, 7] * v + h[i, 8]
            hit[i, j] = w > 1e-9
            if hit[i, j]:
                x[i, j] = (h[i, 0] * u + h[i, 1] * v + h[i, 2]) / w
                y[i, j] = (h[i, 3] * u + h[i, 4] * v + h[i, 5]) / w
            else:
                x[i, j] = y[i, j] = 0.0


@compiled("void(f8[:, ::1], f8, f8[::1], f8[:, ::1])")
def homographies_at(knots: F64, span: float, t: F64, out: F64) -> None:
    """Homographies (9 values a row of ``out``) at times ``t``: the quadratic through the
    ``knots`` at -span, 0 and +span (one knot, the same for all, when ``span`` is 0),
    operation for operation as NumPy's (k1 + a (k2 - k0) / 2 + a^2 ((k0 + k2) / 2 - k1),
    a = t / span): the same bytes without NumPy's broadcasting over rows of 9 (0.1 ms
    a frame's rows)."""
    n = len(t)
    if span == 0.0:
        for i in range(n):
            for j in range(9):
                out[i, j] = knots[0, j]
        return
    c1, c2 = np.empty(9), np.empty(9)
    for j in range(9):
        c1[j] = (knots[2, j] - knots[0, j]) * 0.5
        c2[j] = (knots[0, j] + knots[2, j]) * 0.5 - knots[1, j]
    for i in range(n):
        a = t[i] / span
        aa = a * a
        for j in range(9):
            out[i, j] = knots[1, j] + a * c1[j] + aa * c2[j]


@compiled(
    "b1(f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], "
    "f8[:, ::1], f8[:, ::1], f8[::1])"
)
def grid_paths(
    h0: F64, hl: F64, hh: F64, gu: F64, gv: F64, cols: F64, rows: F64, ex: F64, ey: F64,
    box: F64,
) -> bool:  # fmt: skip
    """The blur's paths on the coarse grid in image px (``ex``, ``ey``): the map path of
    each grid point between its homographies at the exposure's start and end (``hl``,
    ``hh``, per grid row) through the inverse of d(map)/d(image) there (``h0``: at the
    row's time). ``box``: the map box of all those points (x min, y min, x max, y max).
    Returns whether every ray meets the ground (else ``box`` is not set)."""
    n, m = gu.shape
    x0, y0, xl, yl = np.empty((n, m)), np.empty((n, m)), np.empty((n, m)), np.empty((n, m))
    xh, yh = np.empty((n, m)), np.empty((n, m))
    ok, okl, okh = (np.empty((n, m), np.bool_), np.empty((n, m), np.bool_),
                    np.empty((n, m), np.bool_))  # fmt: skip
    _project(h0, gu, gv, x0, y0, ok)
    _project(hl, gu, gv, xl, yl, okl)
    _project(hh, gu, gv, xh, yh, okh)
    a, b, c, d = np.empty((n, m)), np.empty((n, m)), np.empty((n, m)), np.empty((n, m))
    _gradient(x0, cols, 1, a)
    _gradient(x0, rows, 0, b)
    _gradient(y0, cols, 1, c)
    _gradient(y0, rows, 0, d)
    every = True
    lo_x = lo_y = np.inf
    hi_x = hi_y = -np.inf
    for i in range(n):
        for j in range(m):
            good = ok[i, j] and okl[i, j] and okh[i, j]
            every = every and ok[i, j]
            det = a[i, j] * d[i, j] - b[i, j] * c[i, j]
            if abs(det) <= 1e-12:
                det = np.inf
            mx = xh[i, j] - xl[i, j] if good else 0.0
            my = yh[i, j] - yl[i, j] if good else 0.0
            ex[i, j] = (d[i, j] * mx - b[i, j] * my) / det
            ey[i, j] = (a[i, j] * my - c[i, j] * mx) / det
            if ok[i, j]:
                lo_x, hi_x = min(lo_x, x0[i, j]), max(hi_x, x0[i, j])
                lo_y, hi_y = min(lo_y, y0[i, j]), max(hi_y, y0[i, j])
            if good:
                lo_x, hi_x = min(lo_x, xl[i, j], xh[i, j]), max(hi_x, xl[i, j], xh[i, j])
                lo_y, hi_y = min(lo_y, yl[i, j], yh[i, j]), max(hi_y, yl[i, j], yh[i, j])
    box[0], box[1], box[2], box[3] = lo_x, lo_y, hi_x, hi_y
    return every


@compiled("void(f8[::1], f8[:, ::1], f8[:, ::1], f8, f8, f4[:, ::1])")
def grid_keep(r: F64, gu: F64, gv: F64, height_m: float, beta: float, keep: F32) -> None:
    """Haze on the coarse grid: the share of the radiance kept over each ray's range
    (Koschmieder, exp(-beta * range)) to the plane ``height_m`` under the camera (rays
    ``r`` (9): image -> NED); rays that do not descend: 1e6 m."""
    n, m = gu.shape
    for i in range(n):
        for j in range(m):
            u, v = gu[i, j], gv[i, j]
            dn = r[0] * u + r[1] * v + r[2]
            de = r[3] * u + r[4] * v + r[5]
            dd = r[6] * u + r[7] * v + r[8]
            norm = math.sqrt(dn * dn + de * de + dd * dd)
            rng = height_m * norm / max(dd, MIN_DOWN) if dd > MIN_DOWN else 1e6
            keep[i, j] = math.exp(-beta * rng)


@compiled(
    "i8(f4[:, ::1], f4[:, ::1], i8, i8, f8[:, ::1], f8, f8, i8, i8, i8, i8, f4[:, :, ::1], "
    "i8[:, ::1])"
)
def row_maps(
    pu: F64, pv: F64, r0: int, c0: int, rows: F64, ox: float, oy: float, mosaic_w: int,
    mosaic_h: int, strip: int, window_px: int, out: F32, windows: I64,
) -> int:  # fmt: skip
    """Mosaic coordinates of each pixel: pinhole point (pu, pv) (from row ``r0`` and column
    ``c0`` of those grids) through its row's homography ``rows[v]`` (image -> level px),
    less the mosaic's origin; MISS where the ray misses the ground. Returns the count of
    such pixels.

    In strips of ``strip`` rows (``len(windows)`` of them), each strip's coordinates are then taken
    from the corner of the mosaic pixels it samples, ``windows[k]`` (x0, y0, x1, y1): the
    remap reads that window from a copy (see ``effects_frame``), unless it reaches beyond
    the mosaic or is over ``window_px`` pixels, or rays of the strip miss the ground: then
    the whole mosaic (0, 0, w, h), unshifted. Shifting by whole pixels is exact: the
    samples are those of the whole mosaic. A strip is shifted as soon as it is made, while
    it is in the core's cache."""
    height, width = out.shape[0], out.shape[1]
    misses = 0
    flat = out.reshape(height, 2 * width)
    stride = pu.shape[1]
    all_u, all_v = pu.reshape(pu.size), pv.reshape(pv.size)  # 1-D slices: vectorized
    one, tiny, miss = np.float32(1.0), np.float32(1e-9), np.float32(MISS)
    windows[:, 0], windows[:, 1], windows[:, 2], windows[:, 3] = 0, 0, mosaic_w, mosaic_h
    for k in range(len(windows)):
        v0, v1 = k * strip, min(height, (k + 1) * strip)
        missed = 0
        for v in range(v0, v1):
            # The row's homography to the mosaic (its origin taken off in float64), in
            # float32: eight pixels a vector instruction, the coordinates within the
            # mosaic (thousands of px) to a few 1e-4 px (frames within 2 grey levels of
            # float64 maps', 0.04 % of values differing).
            k0, k1, k2, k3, k4, k5, k6, k7, k8 = rows[v]
            h0, h1, h2 = (
                np.float32(k0 - ox * k6),
                np.float32(k1 - ox * k7),
                np.float32(k2 - ox * k8),
            )
            h3, h4, h5 = (
                np.float32(k3 - oy * k6),
                np.float32(k4 - oy * k7),
                np.float32(k5 - oy * k8),
            )
            h6, h7, h8 = np.float32(k6), np.float32(k7), np.float32(k8)
            start = (r0 + v) * stride + c0
            xs, ys = all_u[start : start + width], all_v[start : start + width]
            dst = flat[v]
            for u in range(width):
                x, y = xs[u], ys[u]
                w = h6 * x + h7 * y + h8
                hit = w > tiny
                inv = one / (w if hit else one)  # one division, not two: about half the time
                mx = (h0 * x + h1 * y + h2) * inv
                my = (h3 * x + h4 * y + h5) * inv
                dst[2 * u] = mx if hit else miss
                dst[2 * u + 1] = my if hit else miss
                missed += 0 if hit else 1
        misses += missed
        if missed:
            continue
        # The map's extremes over the strip lie on its border (a smooth map with an
        # invertible Jacobian has no extremum inside), between the border's pixels by far
        # less than the window's margin.
        lo_x = hi_x = flat[v0, 0]
        lo_y = hi_y = flat[v0, 1]
        for v in (v0, v1 - 1):
            for u in range(width):
                lo_x, hi_x = min(lo_x, flat[v, 2 * u]), max(hi_x, flat[v, 2 * u])
                lo_y, hi_y = min(lo_y, flat[v, 2 * u + 1]), max(hi_y, flat[v, 2 * u + 1])
        for v in range(v0, v1):
            for u in (0, width - 1):
                lo_x, hi_x = min(lo_x, flat[v, 2 * u]), max(hi_x, flat[v, 2 * u])
                lo_y, hi_y = min(lo_y, flat[v, 2 * u + 1]), max(hi_y, flat[v, 2 * u + 1])
        # Bilinear sampling at x reads columns floor(x) and floor(x) + 1.
        x0, y0 = math.floor(lo_x) - 1, math.floor(lo_y) - 1
        x1, y1 = math.floor(hi_x) + 3, math.floor(hi_y) + 3
        if x0 < 0 or y0 < 0 or x1 > mosaic_w or y1 > mosaic_h or (x1 - x0) * (y1 - y0) > window_px:
            continue
        windows[k, 0], windows[k, 1], windows[k, 2], windows[k, 3] = x0, y0, x1, y1
        sx, sy = np.float32(x0), np.float32(y0)
        for v in range(v0, v1):
            dst = flat[v]
            for u in range(width):
                dst[2 * u] -= sx
                dst[2 * u + 1] -= sy
    return misses
