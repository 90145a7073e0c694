"""Frames and rotations: WGS84 geodetic <-> ECEF <-> local NED, Euler angles, quaternions.

Functions are named ``src2dst`` (as in pymap3d); metres and radians everywhere unless a name
says ``_deg``. Quaternions are Hamilton, scalar first ``(w, x, y, z)``; ``q_a_to_b`` rotates
vectors expressed in frame a into frame b. Pure Python ``math``: fast enough for 200 Hz loops.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from air_sitl.state import Quat, Vec3

WGS84_A_M = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_B_M = WGS84_A_M * (1.0 - WGS84_F)
GRAVITY_M_S2 = 9.80665
NEAR_POLE_RAD = math.radians(89.0)  # beyond: the height from z (cos(lat) vanishes)


def geodetic2ecef(lat_deg: float, lon_deg: float, alt_m: float) -> Vec3:
    """WGS84 latitude/longitude/ellipsoid height to ECEF metres."""
    lat = math.radians(lat_deg)
    lon = math.radians(lon_deg)
    sin_lat = math.sin(lat)
    n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
    r = (n + alt_m) * math.cos(lat)
    return (r * math.cos(lon), r * math.sin(lon), (n * (1.0 - WGS84_E2) + alt_m) * sin_lat)


def ecef2geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """ECEF metres to WGS84 (lat_deg, lon_deg, alt_m); iterative, sub-millimetre."""
    lat, alt = geodetic_lat_alt(math.hypot(x, y), z)
    return (math.degrees(lat), math.degrees(math.atan2(y, x)), alt)


def geodetic_lat_alt(p: float, z: float) -> tuple[float, float]:
    """Geodetic latitude (rad) and ellipsoid height of the ECEF point at distance ``p`` from
    the polar axis and ``z`` along it (iterated to a fixed point, at most 6 steps)."""
    lat = math.atan2(z, p * (1.0 - WGS84_E2))
    alt = 0.0
    for _ in range(6):
        sin_lat = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
        alt = (
            p / math.cos(lat) - n
            if abs(lat) < NEAR_POLE_RAD
            else z / sin_lat - n * (1.0 - WGS84_E2)
        )
        new = math.atan2(z, p * (1.0 - WGS84_E2 * n / (n + alt)))
        if new == lat:
            break  # a fixed point (2-3 steps at any altitude): the 6 steps end on these bits
        lat = new
    return (lat, alt)


def _ecef2ned_matrix(lat0_deg: float, lon0_deg: float) -> tuple[Vec3, Vec3, Vec3]:
    lat = math.radians(lat0_deg)
    lon = math.radians(lon0_deg)
    sl, cl = math.sin(lat), math.cos(lat)
    so, co = math.sin(lon), math.cos(lon)
    return ((-sl * co, -sl * so, cl), (-so, co, 0.0), (-cl * co, -cl * so, -sl))


class LocalNed:
    """A local NED frame at a fixed origin, its rotation and ECEF origin computed once (a
    filter converting every 20 ms at one home pays only for the conversion itself)."""

    __slots__ = ("_lat_alt", "_m", "_origin")

    def __init__(
        self,
        lat0_deg: float,
        lon0_deg: float,
        alt0_m: float,
        *,
        lat_alt: Callable[[float, float], tuple[float, float]] = geodetic_lat_alt,
    ) -> None:
        """``lat_alt``: :func:`geodetic_lat_alt`, or a compiled twin of it (the filter's)."""
        self._m = _ecef2ned_matrix(lat0_deg, lon0_deg)
        self._origin = geodetic2ecef(lat0_deg, lon0_deg, alt0_m)
        self._lat_alt = lat_alt

    def from_geodetic(self, lat_deg: float, lon_deg: float, alt_m: float) -> Vec3:
        """Position of a WGS84 point in this frame (n, e, d metres)."""
        x, y, z = geodetic2ecef(lat_deg, lon_deg, alt_m)
        x0, y0, z0 = self._origin
        d = (x - x0, y - y0, z - z0)
        m = self._m
        return (
            m[0][0] * d[0] + m[0][1] * d[1] + m[0][2] * d[2],
            m[1][0] * d[0] + m[1][1] * d[1] + m[1][2] * d[2],
            m[2][0] * d[0] + m[2][1] * d[1] + m[2][2] * d[2],
        )

    def to_geodetic(self, n_m: float, e_m: float, d_m: float) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, alt_m) of a point of this frame."""
        m = self._m
        # The matrix is orthonormal: its transpose maps NED back to ECEF.
        dx = m[0][0] * n_m + m[1][0] * e_m + m[2][0] * d_m
        dy = m[0][1] * n_m + m[1][1] * e_m + m[2][1] * d_m
        dz = m[0][2] * n_m + m[1][2] * e_m + m[2][2] * d_m
        x0, y0, z0 = self._origin
        # ecef2geodetic, with this frame's lat_alt.
        x, y, z = x0 + dx, y0 + dy, z0 + dz
        lat, alt = self._lat_alt(math.hypot(x, y), z)
        return (math.degrees(lat), math.degrees(math.atan2(y, x)), alt)


def geodetic2ned(
    lat_deg: float, lon_deg: float, alt_m: float, lat0_deg: float, lon0_deg: float, alt0_m: float
) -> Vec3:
    """Position of a point in the local NED frame whose origin is (lat0, lon0, alt0)."""
    return LocalNed(lat0_deg, lon0_deg, alt0_m).from_geodetic(lat_deg, lon_deg, alt_m)


def ned2geodetic(
    n_m: float, e_m: float, d_m: float, lat0_deg: float, lon0_deg: float, alt0_m: float
) -> tuple[float, float, float]:
    """Inverse of :func:`geodetic2ned`: (lat_deg, lon_deg, alt_m)."""
    return LocalNed(lat0_deg, lon0_deg, alt0_m).to_geodetic(n_m, e_m, d_m)


def ned2enu(v: Vec3) -> Vec3:
    """Swap a NED vector into ENU (x east, y north, z up)."""
    return (v[1], v[0], -v[2])


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle into [-pi, pi)."""
    return (angle_rad + math.pi) % (2.0 * math.pi) - math.pi


def euler2quat(roll_rad: float, pitch_rad: float, yaw_rad: float) -> Quat:
    """Aerospace ZYX Euler angles (yaw, then pitch, then roll) to q_body_to_ned (w, x, y, z)."""
    cr, sr = math.cos(roll_rad / 2), math.sin(roll_rad / 2)
    cp, sp = math.cos(pitch_rad / 2), math.sin(pitch_rad / 2)
    cy, sy = math.cos(yaw_rad / 2), math.sin(yaw_rad / 2)
    return (
        cr * cp * cy + sr * sp * sy,
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
    )


def quat2euler(q: Quat) -> Vec3:
    """q_body_to_ned (w, x, y, z) to ZYX Euler (roll, pitch, yaw) in radians."""
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    s = max(-1.0, min(1.0, 2 * (w * y - z * x)))
    pitch = math.asin(s)
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return (roll, pitch, yaw)


def quat_multiply(a: Quat, b: Quat) -> Quat:
    """Hamilton product a * b (apply b first, then a)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    )


def quat_conjugate(q: Quat) -> Quat:
    """Inverse rotation of a unit quaternion."""
    return (q[0], -q[1], -q[2], -q[3])


def quat_normalize(q: Quat) -> Quat:
    """Unit quaternion with a non-negative scalar part (one canonical sign)."""
    n = math.sqrt(sum(c * c for c in q))
    s = 1.0 / n if q[0] >= 0 else -1.0 / n
    return (q[0] * s, q[1] * s, q[2] * s, q[3] * s)


def quat_rotate(q: Quat, v: Vec3) -> Vec3:
    """Rotate vector v by q (express a body vector in the world frame for q_body_to_world)."""
    w, x, y, z = q
    # v' = v + 2w (u x v) + 2 u x (u x v), u = (x, y, z)
    tx = 2 * (y * v[2] - z * v[1])
    ty = 2 * (z * v[0] - x * v[2])
    tz = 2 * (x * v[1] - y * v[0])
    return (
        v[0] + w * tx + (y * tz - z * ty),
        v[1] + w * ty + (z * tx - x * tz),
        v[2] + w * tz + (x * ty - y * tx),
    )


def quat2matrix(q: Quat) -> tuple[Vec3, Vec3, Vec3]:
    """Rotation matrix (rows) of q: world_vector = M @ body_vector."""
    w, x, y, z = q
    return (
        (1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)),
        (2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)),
        (2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)),
    )


# NED -> ENU is the 180 degree rotation about (1, 1, 0)/sqrt(2); FLU -> FRD is 180 about x.
_S = math.sqrt(0.5)
Q_NED_TO_ENU: Quat = (0.0, _S, _S, 0.0)
Q_FLU_TO_FRD: Quat = (0.0, 1.0, 0.0, 0.0)


def frd2flu(v: Vec3) -> Vec3:
    """A body FRD vector in FLU (ROS's body axes); its own inverse."""
    return (v[0], -v[1], -v[2])


def q_frd_ned_to_flu_enu(q_body_to_ned_wxyz: Quat) -> Quat:
    """Body FRD->NED quaternion (w, x, y, z) as body FLU->ENU (w, x, y, z), scalar part >= 0."""
    q = quat_multiply(quat_multiply(Q_NED_TO_ENU, q_body_to_ned_wxyz), Q_FLU_TO_FRD)
    return q if q[0] >= 0.0 else (-q[0], -q[1], -q[2], -q[3])


def q_flu_enu_to_frd_ned(q_flu_to_enu_wxyz: Quat) -> Quat:
    """Inverse of :func:`q_frd_ned_to_flu_enu` (both fixed rotations are their own inverse)."""
    q = quat_multiply(quat_multiply(Q_NED_TO_ENU, q_flu_to_enu_wxyz), Q_FLU_TO_FRD)
    return q if q[0] >= 0.0 else (-q[0], -q[1], -q[2], -q[3])


def wxyz2xyzw(q: Quat) -> Quat:
    """Scalar-first to scalar-last order (the CSV and ROS order)."""
    return (q[1], q[2], q[3], q[0])
