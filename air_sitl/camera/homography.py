"""3x3 homographies and rotations as row-major 9-tuples, and the geometry of one frame.

Scalar arithmetic on tuples: a frame needs a few dozen products, for which NumPy's per-call
overhead would cost more than the arithmetic.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

Mat3 = npt.NDArray[np.float64]
Mat9 = tuple[float, float, float, float, float, float, float, float, float]

MAX_MOSAIC_HALF_PX = 2048  # limit of the map area read for one frame, per side, at its level
MIN_DOWN = 1e-6  # rays flatter than this (horizon) count as missing the ground


@dataclass(frozen=True, slots=True)
class FrameGeometry:
    """How one frame maps to the map: homography image -> level-0 map px, level, centre."""

    h_img_to_map0: Mat3
    level: int
    center_map_px: tuple[float, float] | None  # image-centre ground point (None: no ground)
    sees_horizon: bool
    height_m: float


def border_points(width_px: int, height_px: int, n: int = 9) -> npt.NDArray[np.float64]:
    """Homogeneous image points along the four edges (n per edge)."""
    us = np.linspace(0, width_px - 1, n)
    vs = np.linspace(0, height_px - 1, n)
    return np.concatenate(
        [
            np.stack([us, np.zeros(n), np.ones(n)], 1),
            np.stack([us, np.full(n, height_px - 1.0), np.ones(n)], 1),
            np.stack([np.zeros(n), vs, np.ones(n)], 1),
            np.stack([np.full(n, width_px - 1.0), vs, np.ones(n)], 1),
        ]
    )


def quat_rows(q: tuple[float, float, float, float]) -> Mat9:
    """Rotation matrix (row-major 9-tuple) of a unit quaternion (w, x, y, z), normalised."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return (
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )  # fmt: skip


def mul3(a: Mat9, b: Mat9) -> Mat9:
    """Product of two 3x3 matrices given as row-major 9-tuples."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = a
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = b
    return (
        a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
        a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
        a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8,
    )  # fmt: skip


def tuple9(m: Mat3) -> Mat9:
    """A 3x3 array as a row-major 9-tuple of floats."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = (float(x) for x in m.ravel())
    return (a0, a1, a2, a3, a4, a5, a6, a7, a8)


def to_mat(m: Mat9) -> Mat3:
    """A row-major 9-tuple as a 3x3 float64 array."""
    return np.array(m, dtype=np.float64).reshape(3, 3)


def to_level(h0: Mat9, level: int) -> Mat9:
    """Homography to level-0 map px -> to level-``level`` px (x_L = (x0 - (s - 1) / 2) / s)."""
    s = float(1 << level)
    off = (s - 1.0) / 2.0
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = h0
    return ((a0 - off * a6) / s, (a1 - off * a7) / s, (a2 - off * a8) / s,
            (a3 - off * a6) / s, (a4 - off * a7) / s, (a5 - off * a8) / s,
            a6, a7, a8)  # fmt: skip


def max_step(h: Mat9, u: float, v: float) -> float:
    """Largest map-pixel step per image pixel of homography ``h`` at image point (u, v).

    The largest singular value of the 2x2 Jacobian d(map x, map y)/d(u, v).
    """
    qx = h[0] * u + h[1] * v + h[2]
    qy = h[3] * u + h[4] * v + h[5]
    w = h[6] * u + h[7] * v + h[8]
    w2 = w * w
    xu, yu = (h[0] * w - qx * h[6]) / w2, (h[3] * w - qy * h[6]) / w2
    xv, yv = (h[1] * w - qx * h[7]) / w2, (h[4] * w - qy * h[7]) / w2
    ssum = xu * xu + yu * yu + xv * xv + yv * yv
    det = xu * yv - yu * xv
    disc = math.sqrt(max(ssum * ssum - 4.0 * det * det, 0.0))
    return math.sqrt((ssum + disc) / 2.0)
