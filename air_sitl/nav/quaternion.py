"""Compiled attitude arithmetic of the filter: Hamilton product, rotation matrix, small rotations.

Attitudes are unit quaternions (w, x, y, z), body FRD -> NED, stored in float64 arrays (the
filter's state vectors) and rotated in place. Callable from Python and from the other
compiled kernels (:mod:`air_sitl.nav.strapdown`, :mod:`air_sitl.nav.kernels`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Vector = npt.NDArray[np.float64]


@compiled("UniTuple(f8, 4)(f8, f8, f8, f8, f8, f8, f8, f8)")
def unit_product(
    aw: float, ax: float, ay: float, az: float, bw: float, bx: float, by: float, bz: float
) -> tuple[float, float, float, float]:
    """The Hamilton product a * b, normalised, scalar part made non-negative."""
    qw = aw * bw - ax * bx - ay * by - az * bz
    qx = aw * bx + ax * bw + ay * bz - az * by
    qy = aw * by - ax * bz + ay * bw + az * bx
    qz = aw * bz + ax * by - ay * bx + az * bw
    inv = 1.0 / math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    if qw < 0.0:
        inv = -inv
    return (qw * inv, qx * inv, qy * inv, qz * inv)


@compiled("UniTuple(f8, 9)(f8, f8, f8, f8)")
def rotation(w: float, x: float, y: float, z: float) -> tuple[float, ...]:
    """Row-major body->NED rotation matrix of the quaternion (9 floats)."""
    return (
        1 - 2 * (y * y + z * z),
        2 * (x * y - w * z),
        2 * (x * z + w * y),
        2 * (x * y + w * z),
        1 - 2 * (x * x + z * z),
        2 * (y * z - w * x),
        2 * (x * z - w * y),
        2 * (y * z + w * x),
        1 - 2 * (x * x + y * y),
    )


@compiled("void(f8[::1], i8, f8, f8, f8)")
def rotate_global(s: Vector, k: int, ax: float, ay: float, az: float) -> None:
    """q = exp(dtheta) * q for the quaternion at ``s[k:k + 4]``: a small rotation expressed in
    NED applied to an attitude."""
    angle = math.sqrt(ax * ax + ay * ay + az * az)
    if angle > 1e-9:
        f = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    else:
        f, c = 0.5, 1.0
    s[k], s[k + 1], s[k + 2], s[k + 3] = unit_product(
        c, ax * f, ay * f, az * f, s[k], s[k + 1], s[k + 2], s[k + 3]
    )


@compiled("f8(f8)")
def wrap_pi(a: float) -> float:
    """``a`` wrapped to [-pi, pi] (exact, as math.remainder(a, 2 pi), for |a| <= 3 pi)."""
    two_pi = 2.0 * math.pi
    n = np.round(a / two_pi)
    return a - n * two_pi if n != 0.0 else a
