"""The truth state's arithmetic of :class:`air_sitl.fdm.jsbsim_model.JSBSimModel` compiled
(:mod:`air_sitl.compiled`, group ``flight``): geodetic to NED about the home's origin and
Euler angles to the quaternion (``frames.euler2quat``), operation for operation as the
Python was (the same bytes: numba's ``%`` of floats is CPython's, fmod and the sign fix).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled
from air_sitl.frames import WGS84_A_M, WGS84_E2

Array = npt.NDArray[np.float64]
_PI = math.pi
_TWO_PI = 2.0 * math.pi
# The origin's array: its ECEF position, then the rows of ECEF to NED (its last zero left out).
X0, Y0, Z0, R = 0, 1, 2, 3


@compiled("Tuple((UniTuple(f8, 3), UniTuple(f8, 4), f8))(f8[::1], f8, f8, f8, f8, f8, f8)")
def truth(
    origin: Array,
    lat_deg: float,
    lon_deg: float,
    alt_m: float,
    phi: float,
    theta: float,
    psi: float,
) -> tuple[tuple[float, float, float], tuple[float, float, float, float], float]:
    """((north, east, down), (qw, qx, qy, qz), yaw in [-pi, pi)) of a geodetic position and
    ZYX Euler angles, about ``origin``: VehicleState's tuples as they are (no slicing)."""
    yaw = (psi + _PI) % _TWO_PI - _PI
    lat_r = math.radians(lat_deg)
    lon_r = math.radians(lon_deg)
    sin_lat = math.sin(lat_r)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    r = (n + alt_m) * math.cos(lat_r)
    dx = r * math.cos(lon_r) - origin[X0]
    dy = r * math.sin(lon_r) - origin[Y0]
    dz = (n * (1.0 - WGS84_E2) + alt_m) * sin_lat - origin[Z0]
    cr, sr = math.cos(phi / 2), math.sin(phi / 2)
    cp, sp = math.cos(theta / 2), math.sin(theta / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    ned = (
        origin[R] * dx + origin[R + 1] * dy + origin[R + 2] * dz,
        origin[R + 3] * dx + origin[R + 4] * dy,
        origin[R + 5] * dx + origin[R + 6] * dy + origin[R + 7] * dz,
    )
    quat = (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )
    return ned, quat, yaw
