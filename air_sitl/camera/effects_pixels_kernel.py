"""The compiled passes over a frame's sampled pixels for the camera effects (numba,
``air_sitl.compiled``, group ``effects`` with :mod:`air_sitl.camera.effects_kernel`): the
motion blur (a line kernel per region of like paths, its weights in 1/256 and its sums in
16-bit integers: twice the pixels a vector instruction of float32 sums, within 1 grey level
of them, with the auto exposure's metering as it writes) and the light (haze, vignetting, the
auto exposure's gain and the sensor noise in one pass).

The loops are written so that LLVM vectorizes them (rows as flat arrays, the channels at
constant strides, no branch per pixel): without ``fastmath`` each operation rounds as
written, so vectorizing changes no byte. Sums over a frame are kept per column and added at
the end (vectorizable, and the same bytes built or under numba's JIT).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled, compiled_inline

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]
I64 = npt.NDArray[np.int64]
U16 = npt.NDArray[np.uint16]

UNIFORM_PX = 1.0  # the blur's paths vary by less over a region: one kernel for all of it
TILE_PX = 64  # the blur's smallest regions where the motion varies over the frame
MAX_TAPS = 16  # taps along the longest path
FIXED_BITS = 8  # the blur's weights in units of 1 / 2**FIXED_BITS: its sums fit 16 bits
FIXED_ONE = 1 << FIXED_BITS


@compiled
def _edge(nodes: F64, i: int) -> int:
    """The first pixel nearer grid node ``i`` than node ``i - 1`` (0; the size at the end)."""
    if i <= 0:
        return 0
    n = len(nodes)
    if i >= n:
        return round(float(nodes[n - 1] + (nodes[n - 1] - nodes[n - 2]) / 2.0 + 0.5))
    return math.ceil(float(nodes[i - 1] + nodes[i]) / 2.0)


@compiled
def _line_taps(ex: float, ey: float, taps: I64, weights: F32) -> tuple[int, int, int]:
    """A blur path (ex, ey) image px long as correlation taps about a pixel apart at
    s = (k + 1/2) / n - 1/2 along it, each spread bilinearly: (row, column) offsets from
    the output pixel in ``taps``, their weights, row by row as the kernel's non-zero
    entries; returns (count, rows, columns) of the kernel."""
    n = min(MAX_TAPS, max(1, math.ceil(math.hypot(ex, ey) + 0.5)))
    xs, ys = np.empty(n), np.empty(n)
    for k in range(n):
        s = (k + 0.5) / n - 0.5
        xs[k], ys[k] = s * ex, s * ey
    x0, y0 = math.floor(xs.min()), math.floor(ys.min())
    kh, kw = math.floor(ys.max()) - y0 + 2, math.floor(xs.max()) - x0 + 2
    kernel = np.zeros((kh, kw), np.float32)
    for k in range(n):
        ix, iy = math.floor(xs[k]), math.floor(ys[k])
        fx, fy = xs[k] - ix, ys[k] - iy
        kernel[iy - y0, ix - x0] += (1 - fx) * (1 - fy) / n
        kernel[iy - y0, ix - x0 + 1] += fx * (1 - fy) / n
        kernel[iy - y0 + 1, ix - x0] += (1 - fx) * fy / n
        kernel[iy - y0 + 1, ix - x0 + 1] += fx * fy / n
    count = 0
    for i in range(kh):
        for j in range(kw):
            if kernel[i, j] != 0.0:
                taps[count, 0], taps[count, 1] = i + y0, j + x0
                weights[count] = kernel[i, j]
                count += 1
    return count, kh, kw


@compiled_inline
def _tap_row(src: U8, rows: int, y: int, x: int, nw: int, taps: I64, t: int) -> U8:
    """The ``4 * nw`` values tap ``t`` reads for the pixels from (x, y) of ``src`` (BGRA
    rows, ``rows`` of them, flat; its row clamped to them, its columns within them)."""
    sy = min(max(y + taps[t, 0], 0), rows - 1)
    at = sy * (len(src) // rows) + 4 * (x + taps[t, 1])
    out: U8 = src[at : at + 4 * nw]
    return out


@compiled
def _fixed_weights(weights: F32, count: int, fixed: U16) -> None:
    """The taps' weights (their sum 1) in units of 1/FIXED_ONE summing to FIXED_ONE: each
    rounded down, then one unit more to those with the largest remainders."""
    left = FIXED_ONE
    rest = np.empty(count)
    for t in range(count):
        scaled = float(weights[t]) * FIXED_ONE
        fixed[t] = math.floor(scaled)
        rest[t] = scaled - math.floor(scaled)
        left -= fixed[t]
    for _ in range(max(left, 0)):
        best = 0
        for t in range(count):
            if rest[t] > rest[best]:
                best = t
        fixed[best] += 1
        rest[best] = -1.0


@compiled
def _blur_region(
    sharp: U8, pad: int, y0: int, y1: int, x0: int, x1: int, taps: I64, weights: U16,
    count: int, acc: U16, out: U8, keep: F32, keep_at: F32, vignette: F32, air: F64,
    col: F64, kept: F32,
) -> None:  # fmt: skip
    """Output pixels [y0, y1) x [x0, x1) (BGRA): the taps' weighted sum of ``sharp``
    (the frame and ``pad`` pixels around it; beyond it, its edge repeated), in integers
    (``weights`` in units of 1/FIXED_ONE, summing to FIXED_ONE; rounded to the nearest,
    halves up); their light added to the columns' sums ``col`` (:func:`_meter`, the haze's
    row from ``keep`` at ``keep_at`` into ``kept``) unless ``col`` is empty. The sums fit
    16 bits (255 * FIXED_ONE + FIXED_ONE / 2): sixteen pixel values a vector instruction."""
    sh, sw = sharp.shape[0], sharp.shape[1]
    width = out.shape[1]
    all_vignette = vignette.reshape(vignette.size)
    src = sharp.reshape(sh, 4 * sw)
    dst = out.reshape(out.size)
    nw = x1 - x0
    every = sharp.reshape(sharp.size)  # 1-D slices: vectorized
    # Whether every tap's columns lie within ``sharp`` (then four taps at a time).
    inside = True
    for t in range(count):
        sx = x0 + pad + taps[t, 1]
        inside = inside and sx >= 0 and sx + nw <= sw
    half = np.uint16(FIXED_ONE // 2)
    for y in range(y0, y1):
        row = acc[: 4 * nw]
        row[:] = half
        first = 0
        while inside and first + 4 <= count:  # four taps a pass over the row
            s0 = _tap_row(every, sh, y + pad, x0 + pad, nw, taps, first)
            s1 = _tap_row(every, sh, y + pad, x0 + pad, nw, taps, first + 1)
            s2 = _tap_row(every, sh, y + pad, x0 + pad, nw, taps, first + 2)
            s3 = _tap_row(every, sh, y + pad, x0 + pad, nw, taps, first + 3)
            w0, w1, w2, w3 = weights[first : first + 4]
            for i in range(4 * nw):
                row[i] = np.uint16(row[i] + w0 * np.uint16(s0[i]) + w1 * np.uint16(s1[i])
                                   + w2 * np.uint16(s2[i]) + w3 * np.uint16(s3[i]))  # fmt: skip
            first += 4
        for t in range(first, count):
            sy = min(max(y + pad + taps[t, 0], 0), sh - 1)
            sx = x0 + pad + taps[t, 1]  # sharp's column of the region's first pixel
            wt = weights[t]
            line = src[sy]
            lo, hi = min(max(-sx, 0), nw), max(min(sw - sx, nw), 0)
            if lo < hi:
                seg = line[4 * (sx + lo) : 4 * (sx + hi)]
                part = row[4 * lo : 4 * hi]
                for i in range(4 * (hi - lo)):
                    part[i] = np.uint16(part[i] + wt * np.uint16(seg[i]))
            for p in range(lo):  # columns beyond the left edge: its first column
                for c in range(4):
                    row[4 * p + c] = np.uint16(row[4 * p + c] + wt * np.uint16(line[c]))
            for p in range(hi, nw):  # and the right's last
                for c in range(4):
                    last = np.uint16(line[4 * (sw - 1) + c])
                    row[4 * p + c] = np.uint16(row[4 * p + c] + wt * last)
        out_row = dst[4 * (y * width + x0) : 4 * (y * width + x1)]
        for i in range(4 * nw):
            out_row[i] = np.uint8(row[i] >> FIXED_BITS)
        if len(col):
            at = y * width
            _keep_row(keep, keep_at, y, x0, x1, kept)
            _meter(out_row, kept[: x1 - x0], all_vignette[at + x0 : at + x1], air,
                   col[x0:x1])  # fmt: skip


@compiled(
    "f8(u1[:, :, ::1], i8, f8[:, ::1], f8[:, ::1], f8[::1], f8[::1], f4[:, ::1], f4[:, ::1], "
    "f4[:, ::1], f8[::1], b1, u1[:, :, ::1])"
)
def blur(
    sharp: U8, pad: int, ex: F64, ey: F64, rows: F64, cols: F64, keep: F32, keep_at: F32,
    vignette: F32, air: F64, meter: bool, out: U8,
) -> float:  # fmt: skip
    """Motion blur of the frame in ``sharp`` (BGRA, ``pad`` px around it) into ``out``:
    regions of the grid (nodes ``rows``, ``cols``) whose paths (``ex``, ``ey``) differ by
    under UNIFORM_PX (split in four until they do, down to TILE_PX) each filtered with the
    line kernel of their mean path, rounded to 1/16 px. Returns the blurred frame's
    :func:`light_total` if ``meter`` (measured on each row as it is made), else 0."""
    stack = np.empty((256, 4), np.int64)
    stack[0, 0], stack[0, 1], stack[0, 2], stack[0, 3] = 0, len(rows), 0, len(cols)
    top = 1
    taps = np.empty((4 * MAX_TAPS, 2), np.int64)  # a tap spreads over 4 pixels
    weights = np.empty(4 * MAX_TAPS, np.float32)
    fixed = np.empty(4 * MAX_TAPS, np.uint16)
    acc = np.empty(4 * out.shape[1], np.uint16)
    col = np.zeros(out.shape[1] if meter else 0)
    kept = np.empty(out.shape[1], np.float32)
    while top > 0:
        top -= 1
        i0, i1, j0, j1 = stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3]
        y0, y1 = _edge(rows, i0), _edge(rows, i1)
        x0, x1 = _edge(cols, j0), _edge(cols, j1)
        px, py = ex[i0:i1, j0:j1], ey[i0:i1, j0:j1]
        spread = max(px.max() - px.min(), py.max() - py.min())
        if spread >= UNIFORM_PX and max(y1 - y0, x1 - x0) > TILE_PX:
            im, jm = (i0 + i1) // 2, (j0 + j1) // 2
            for a, b, c, d in ((i0, im, j0, jm), (i0, im, jm, j1), (im, i1, j0, jm),
                               (im, i1, jm, j1)):  # fmt: skip
                if a < b and c < d:
                    stack[top, 0], stack[top, 1], stack[top, 2], stack[top, 3] = a, b, c, d
                    top += 1
            continue
        kx, ky = np.rint(px.mean() * 16.0) / 16.0, np.rint(py.mean() * 16.0) / 16.0
        count, _, _ = _line_taps(kx, ky, taps, weights)
        _fixed_weights(weights, count, fixed)
        _blur_region(sharp, pad, y0, y1, x0, x1, taps, fixed, count, acc, out, keep, keep_at,
                     vignette, air, col, kept)  # fmt: skip
    return float(col.sum())


@compiled_inline
def _keep_row(keep: F32, keep_at: F32, v: int, x0: int, x1: int, out: F32) -> None:
    """The haze's share kept over columns [x0, x1) of sensor row ``v`` into ``out``: the
    blend of two rows of ``keep`` (the coarse grid's rows interpolated along the sensor's
    columns) by ``keep_at[v]`` = (first row, second row, their weights), as ``cv2.resize``
    (INTER_LINEAR) blends them: the full-size array is never made."""
    r0, r1 = keep[int(keep_at[v, 0])], keep[int(keep_at[v, 1])]
    b0, b1 = keep_at[v, 2], keep_at[v, 3]
    for u in range(x1 - x0):
        out[u] = r0[x0 + u] * b0 + r1[x0 + u] * b1


@compiled_inline
def _meter(px: U8, keep: F32, vignette: F32, air: F64, col: F64) -> None:
    """Add each pixel's colours after haze (``keep`` of the radiance, the rest airlight
    ``air``) and vignetting to its column's sum ``col``: a row of BGRA pixels ``px``. The
    three colours at once: (B + G + R) * a + (the airlight's sum) * b, with a = keep *
    vignetting and b = (1 - keep) * vignetting."""
    airs = air[0] + air[1] + air[2]
    for u in range(len(col)):
        k = keep[u]
        gain = vignette[u]
        s = np.int32(px[4 * u]) + np.int32(px[4 * u + 1]) + np.int32(px[4 * u + 2])
        col[u] += np.float64(s) * (k * gain) + airs * ((1.0 - k) * gain)


@compiled("f8(u1[:, :, ::1], f4[:, ::1], f4[:, ::1], f4[:, ::1], f8[::1])")
def light_total(img: U8, keep: F32, keep_at: F32, vignette: F32, air: F64) -> float:
    """The sum over a BGRA frame's colours after haze (``keep`` at ``keep_at``:
    :func:`_keep_row`) and vignetting (the auto exposure's measure; :func:`light`)."""
    height, width = vignette.shape
    flat = img.reshape(height, 4 * width)
    col = np.zeros(width)
    kept = np.empty(width, np.float32)
    for v in range(height):
        _keep_row(keep, keep_at, v, 0, width, kept)
        _meter(flat[v], kept, vignette[v], air, col)
    return float(col.sum())


@compiled(
    "void(u1[:, :, ::1], f4[:, ::1], f4[:, ::1], f4[:, ::1], f8[::1], f8, u1[:, :, ::1], "
    "u1[:, :, ::1], u1[:, :, ::1])"
)
def light(
    img: U8, keep: F32, keep_at: F32, vignette: F32, air: F64, gain: float, pos: U8, neg: U8,
    out: U8,
) -> None:  # fmt: skip
    """Haze and vignetting of a BGRA frame (as :func:`light_total`) times ``gain``, rounded
    to the nearest (half to even) and saturated, plus the sensor noise (``pos`` less
    ``neg``: clip(pixel + noise), as ``Renderer._noised``; zero-sized: none) into BGR
    ``out``. In float32, the gain in each pixel's two factors (its radiance's and the
    airlight's): eight values a vector instruction."""
    height, width = vignette.shape
    g = np.float32(gain)
    one = np.float32(1.0)
    a0, a1, a2 = np.float32(air[0]), np.float32(air[1]), np.float32(air[2])
    top, zero = np.float32(255.0), np.float32(0.0)
    flat = img.reshape(height, 4 * width)
    dst = out.reshape(height, 3 * width)
    noisy = pos.size > 0
    up = pos.reshape(height if noisy else 0, 3 * width)
    down = neg.reshape(height if noisy else 0, 3 * width)
    line = np.zeros(3 * width, np.float32)
    kr = np.empty(width, np.float32)
    for v in range(height):
        _keep_row(keep, keep_at, v, 0, width, kr)
        gr, px, o = vignette[v], flat[v], dst[v]
        for u in range(width):
            k = kr[u]
            vg = gr[u] * g
            a = k * vg
            b = (one - k) * vg
            line[3 * u] = min(np.rint(np.float32(px[4 * u]) * a + a0 * b), top)
            line[3 * u + 1] = min(np.rint(np.float32(px[4 * u + 1]) * a + a1 * b), top)
            line[3 * u + 2] = min(np.rint(np.float32(px[4 * u + 2]) * a + a2 * b), top)
        if noisy:
            p, q = up[v], down[v]
            for i in range(3 * width):
                o[i] = np.uint8(min(max(line[i] + np.float32(p[i]) - np.float32(q[i]), zero), top))
        else:
            for i in range(3 * width):
                o[i] = np.uint8(line[i])
