"""The filter's 50 Hz conversions of its estimate compiled (:mod:`air_sitl.compiled`, group
``nav``): :func:`air_sitl.frames.geodetic_lat_alt` (the latitude's fixed-point iteration of
the estimate's position, :meth:`air_sitl.frames.LocalNed.to_geodetic`) and
:func:`air_sitl.frames.quat2euler`, operation for operation as the Python (the same bytes:
``min`` and ``max`` written out, choosing as the builtins do; ``math.hypot``, whose CPython
rounding is its own, stays in the Python caller).
"""

from __future__ import annotations

import math

from air_sitl.compiled import compiled
from air_sitl.frames import NEAR_POLE_RAD, WGS84_A_M, WGS84_E2


@compiled("UniTuple(f8, 2)(f8, f8)")
def lat_alt(p: float, z: float) -> tuple[float, float]:
    """Geodetic latitude (rad) and ellipsoid height of the ECEF point at distance ``p`` from
    the polar axis and ``z`` along it (iterated to a fixed point, at most 6 steps)."""
    lat = math.atan2(z, p * (1.0 - WGS84_E2))
    alt = 0.0
    for _ in range(6):
        sin_lat = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
        if abs(lat) < NEAR_POLE_RAD:
            alt = p / math.cos(lat) - n
        else:
            alt = z / sin_lat - n * (1.0 - WGS84_E2)
        new = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + alt)))
        if new == lat:
            break
        lat = new
    return (lat, alt)


@compiled("UniTuple(f8, 3)(f8, f8, f8, f8)")
def euler(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
    """q_body_to_ned (w, x, y, z) to ZYX Euler (roll, pitch, yaw) in radians."""
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    s = s if s < 1.0 else 1.0  # min(1.0, s)
    s = s if s > -1.0 else -1.0  # max(-1.0, s)
    pitch = math.asin(s)
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return (roll, pitch, yaw)
