"""The compiled loops of the camera effects (numba, ``air_sitl.compiled``): the map of a
frame's pixels (each row through its own homography, at the pinhole points of the lens),
and the light (haze and vignetting, with the frame's sum for the auto exposure). The
sampling and the motion blur are OpenCV's (``effects_frame``)."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

F32 = npt.NDArray[np.float32]
F64 = npt.NDArray[np.float64]
U8 = npt.NDArray[np.uint8]

MISS = -1e7  # a map coordinate far off any mosaic: the fill colour
# The kernels' signatures (numba's notation, air_sitl.compiled): f8[:, :] a float64 image,
# a view (the pinhole points of the frame's cut), f4[:, :, ::1] a contiguous float32 one.


@compiled("i8(f8[:, :], f8[:, :], f8[:, ::1], f8, f8, f4[:, :, ::1])")
def row_maps(pu: F64, pv: F64, rows: F64, ox: float, oy: float, out: F32) -> int:
    """Mosaic coordinates of each pixel: pinhole point (pu, pv) through its row's
    homography ``rows[v]`` (image -> level px), less the mosaic's origin; MISS where the ray
    misses the ground. Returns the count of such pixels."""
    height, width = pu.shape
    misses = 0
    for v in range(height):
        h0, h1, h2, h3, h4, h5, h6, h7, h8 = rows[v]
        for u in range(width):
            x, y = pu[v, u], pv[v, u]
            w = h6 * x + h7 * y + h8
            if w > 1e-9:
                out[v, u, 0] = (h0 * x + h1 * y + h2) / w - ox
                out[v, u, 1] = (h3 * x + h4 * y + h5) / w - oy
            else:
                out[v, u, 0] = MISS
                out[v, u, 1] = MISS
                misses += 1
    return misses


@compiled("f8(u1[:, :, ::1], f4[:, ::1], f4[:, ::1], f8[::1], f4[:, :, ::1])")
def light(img: U8, keep: F32, vignette: F32, air: F64, out: F32) -> float:
    """Haze (``keep`` of the radiance, the rest airlight) and vignetting of a BGRA frame
    into BGR ``out``; returns the sum of ``out``."""
    height, width = keep.shape
    total = 0.0
    for v in range(height):
        for u in range(width):
            k = keep[v, u]
            gain = vignette[v, u]
            a = k * gain
            b = (1.0 - k) * gain
            for c in range(3):
                value = img[v, u, c] * a + air[c] * b
                out[v, u, c] = value
                total += value
    return total
