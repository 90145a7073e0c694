"""Compiled kernels of the filter (numba), each giving the bits of the Python it replaces.

Float arithmetic is IEEE double in both (no fused multiply-add, no fastmath) and sin, cos,
sqrt and atan2 are the C library's in both, so a compiled twin of a pure-float function
returns what CPython computes, in a fraction of the time (``tests/nav/test_units.py`` checks
it). Not hypot: CPython has its own, so callers pass it in.

``cache=True``: the machine code is compiled once and loaded from ``__pycache__`` by later
processes (where numba finds no writable place it compiles anew in each process).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numba

from air_sitl import frames


def jit(fn: Callable[..., Any]) -> Any:
    """numba.njit with IEEE division (error_model "numpy": no Python check per division; a
    division by zero, at the Earth's centre only, gives inf or nan instead of raising),
    cached on disk where numba can."""
    try:
        return numba.njit(fn, cache=True, error_model="numpy")
    except RuntimeError:  # numba: "cannot cache function ...: no locator available"
        return numba.njit(fn, error_model="numpy")


@jit
def position_std(P):  # type: ignore[no-untyped-def]
    """(larger axis of the horizontal 1-sigma ellipse, vertical 1-sigma) of P, metres."""
    a, b, c = P[0, 0], P[0, 1], P[1, 1]
    big = 0.5 * (a + c) + math.sqrt(max(0.0, 0.25 * (a - c) ** 2 + b * b))
    return math.sqrt(max(big, 0.0)), math.sqrt(max(P[2, 2], 0.0))


# The estimate's latitude and height: frames.geodetic_lat_alt compiled (the same source, so
# the same bits: its sin, cos, sqrt and atan2 are the C library's, as in CPython).
geodetic_lat_alt = jit(frames.geodetic_lat_alt)
