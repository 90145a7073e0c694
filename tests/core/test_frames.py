"""Round trips and reference values of the frame conversions."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from air_sitl import frames


def test_geodetic2ecef_reference_values() -> None:
    # Equator / prime meridian sits at the semi-major axis; the pole at the semi-minor axis.
    x, y, z = frames.geodetic2ecef(0.0, 0.0, 0.0)
    assert (x, y, z) == (frames.WGS84_A_M, 0.0, 0.0)
    x, y, z = frames.geodetic2ecef(90.0, 0.0, 0.0)
    assert abs(z - frames.WGS84_B_M) < 1e-6
    assert abs(x) < 1e-6


def test_ned_offsets_match_metres_per_degree() -> None:
    # One arc-minute of latitude is about one nautical mile near 45 degrees (1852 m, +-0.5%).
    n, e, d = frames.geodetic2ned(45.0 + 1 / 60, 10.0, 100.0, 45.0, 10.0, 100.0)
    assert abs(n - 1852.0) / 1852.0 < 0.005
    assert abs(e) < 1e-6
    assert abs(d) < 0.3  # earth curvature drop over 1.85 km is about 0.27 m
    n, e, d = frames.geodetic2ned(45.0, 10.001, 100.0, 45.0, 10.0, 100.0)
    assert abs(e - 78.8) < 0.2  # 111.32 km * cos(45 deg) * 0.001
    assert abs(n) < 0.01


@given(
    st.floats(-80, 80),
    st.floats(-179, 179),
    st.floats(-5000, 5000),
    st.floats(-5000, 5000),
    st.floats(-3000, 100),
)
def test_ned_round_trip(lat0: float, lon0: float, n: float, e: float, d: float) -> None:
    lat, lon, alt = frames.ned2geodetic(n, e, d, lat0, lon0, 200.0)
    n2, e2, d2 = frames.geodetic2ned(lat, lon, alt, lat0, lon0, 200.0)
    assert math.dist((n, e, d), (n2, e2, d2)) < 1e-4


@given(st.floats(-3.0, 3.0), st.floats(-1.5, 1.5), st.floats(-3.1, 3.1))
def test_euler_quaternion_round_trip(roll: float, pitch: float, yaw: float) -> None:
    q = frames.euler2quat(roll, pitch, yaw)
    assert abs(sum(c * c for c in q) - 1.0) < 1e-12
    r2, p2, y2 = frames.quat2euler(q)
    assert abs(frames.wrap_pi(r2 - roll)) < 1e-9
    assert abs(p2 - pitch) < 1e-9
    assert abs(frames.wrap_pi(y2 - yaw)) < 1e-9


def test_yaw_90_rotates_nose_to_east() -> None:
    q = frames.euler2quat(0.0, 0.0, math.pi / 2)
    nose_ned = frames.quat_rotate(q, (1.0, 0.0, 0.0))
    assert math.dist(nose_ned, (0.0, 1.0, 0.0)) < 1e-12
    m = frames.quat2matrix(q)
    assert math.dist(tuple(row[0] for row in m), (0.0, 1.0, 0.0)) < 1e-12


def test_roll_right_puts_right_wing_down() -> None:
    q = frames.euler2quat(math.radians(30), 0.0, 0.0)
    right_wing = frames.quat_rotate(q, (0.0, 1.0, 0.0))
    assert right_wing[2] > 0.49  # +z is down in NED


def test_quat_multiply_composes_rotations() -> None:
    a = frames.euler2quat(0.0, 0.0, 0.3)
    b = frames.euler2quat(0.0, 0.0, 0.4)
    ab = frames.quat_multiply(a, b)
    assert abs(frames.quat2euler(ab)[2] - 0.7) < 1e-12
    assert frames.quat_normalize((-1.0, 0.0, 0.0, 0.0)) == (1.0, -0.0, -0.0, -0.0)
