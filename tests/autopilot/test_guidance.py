"""Guidance math: L1 line following, L1 loiter, altitude ramp, turn anticipation."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from air_sitl.autopilot import guidance as gd

G = 9.80665
LIM = math.radians(35.0)
KW = {"period_s": 16.0, "damping": 0.75, "bank_limit_rad": LIM}


def _fly_line(pn: float, pe: float, course: float, seconds: float, wind=(0.0, 0.0)):
    """Kinematic coordinated turns at 15 m/s along the north-going line through the origin."""
    v, phi, dt = 15.0, 0.0, 0.02
    worst_late = 0.0
    xt = 0.0
    for i in range(int(seconds / dt)):
        vn = v * math.cos(course) + wind[0]
        ve = v * math.sin(course) + wind[1]
        r = gd.follow_line(pn, pe, vn, ve, (0.0, 0.0), (10000.0, 0.0), **KW)
        assert abs(r.bank_rad) <= LIM + 1e-12
        xt = r.cross_track_m
        if i * dt > seconds / 2:
            worst_late = max(worst_late, abs(xt))
        phi += (r.bank_rad - phi) * dt / 0.3
        course += G * math.tan(phi) / v * dt
        pn += vn * dt
        pe += ve * dt
    return xt, worst_late


def test_line_bank_sign_and_size() -> None:
    on = gd.follow_line(0.0, 0.0, 15.0, 0.0, (-100.0, 0.0), (100.0, 0.0), **KW)
    assert on.bank_rad == 0.0 and on.cross_track_m == 0.0
    assert on.along_track_m == 100.0 and on.leg_length_m == 200.0
    right = gd.follow_line(0.0, 20.0, 15.0, 0.0, (-100.0, 0.0), (100.0, 0.0), **KW)
    assert right.cross_track_m == 20.0 and right.bank_rad < 0.0  # right of track: turn left
    left = gd.follow_line(0.0, -20.0, 15.0, 0.0, (-100.0, 0.0), (100.0, 0.0), **KW)
    assert left.cross_track_m == -20.0 and left.bank_rad == -right.bank_rad
    # Far off: intercept at 45 degrees, not more (bank goes to 0 once on the intercept course).
    far = gd.follow_line(0.0, -500.0, 15 * math.cos(math.pi / 4), 15 * math.sin(math.pi / 4),
                         (-100.0, 0.0), (100.0, 0.0), **KW)  # fmt: skip
    assert abs(far.bank_rad) < 1e-9
    # Flying the wrong way: full bank.
    away = gd.follow_line(0.0, 0.0, -15.0, 0.0, (-100.0, 0.0), (100.0, 0.0), **KW)
    assert abs(away.bank_rad) == LIM


def test_far_behind_a_heads_for_a_first() -> None:
    # 500 m behind A and off to the east: course should point at A, not along the line.
    r = gd.follow_line(-500.0, 300.0, 0.0, -15.0, (0.0, 0.0), (1000.0, 0.0), **KW)
    bearing_to_a = math.atan2(-300.0, 500.0)  # north-west
    # Flying west (course -90 deg); A is at -31 deg: it must turn right.
    assert r.bank_rad > 0.0 and bearing_to_a > -math.pi / 2


def test_line_converges_without_overshoot_beyond_limits() -> None:
    for offset in (-150.0, -30.0, 40.0, 200.0):
        xt, late = _fly_line(0.0, offset, 0.0, 120.0)
        assert abs(xt) < 0.5, offset
        assert late < 1.0, offset


def test_line_converges_in_crosswind() -> None:
    xt, late = _fly_line(0.0, 60.0, 0.0, 150.0, wind=(0.0, 6.0))
    assert abs(xt) < 1.0 and late < 2.0


@given(
    pn=st.floats(-2000, 2000), pe=st.floats(-2000, 2000), vn=st.floats(-25, 25),
    ve=st.floats(-25, 25), bn=st.floats(-2000, 2000), be=st.floats(-2000, 2000),
)  # fmt: skip
def test_line_bank_always_within_limit(
    pn: float, pe: float, vn: float, ve: float, bn: float, be: float
) -> None:
    r = gd.follow_line(pn, pe, vn, ve, (0.0, 0.0), (bn, be), **KW)
    assert abs(r.bank_rad) <= LIM
    assert math.isfinite(r.cross_track_m) and math.isfinite(r.course_rad)


def _fly_circle(pn, pe, course, direction, seconds, wind=(0.0, 0.0), radius=160.0):
    v, phi, dt = 15.0, 0.0, 0.02
    errs = []
    swept = 0.0
    last = None
    for i in range(int(seconds / dt)):
        vn = v * math.cos(course) + wind[0]
        ve = v * math.sin(course) + wind[1]
        c = gd.follow_circle(pn, pe, vn, ve, (0.0, 0.0), radius, direction, **KW)
        if i * dt > seconds / 2:
            errs.append(abs(c.radial_error_m))
            if last is not None:
                swept += gd.angle_travelled(last, c.angle_rad, direction)
            last = c.angle_rad
        phi += (c.bank_rad - phi) * dt / 0.3
        course += G * math.tan(phi) / v * dt
        pn += vn * dt
        pe += ve * dt
    return max(errs), swept


def test_circle_steady_bank_matches_centripetal() -> None:
    # On a 160 m circle at its north point flying east: clockwise, the centre on the right.
    c = gd.follow_circle(160.0, 0.0, 0.0, 15.0, (0.0, 0.0), 160.0, 1, **KW)
    assert abs(c.bank_rad - math.atan(15.0**2 / 160.0 / G)) < 1e-9
    assert c.radial_error_m == 0.0 and not c.capturing
    assert c.angle_rad == 0.0 and abs(c.course_rad - math.pi / 2) < 1e-12
    ccw = gd.follow_circle(160.0, 0.0, 0.0, -15.0, (0.0, 0.0), 160.0, -1, **KW)
    assert ccw.bank_rad == -c.bank_rad and abs(ccw.course_rad + math.pi / 2) < 1e-12


def test_circle_capture_from_outside_and_inside_both_directions() -> None:
    for start, course in (((600.0, 300.0), math.pi), ((0.0, 10.0), 0.0), ((-170.0, 0.0), 1.0)):
        for direction in (1, -1):
            worst, swept = _fly_circle(start[0], start[1], course, direction, 240.0)
            assert worst < 2.0, (start, direction)
            assert swept > 0.0, "flies in the commanded direction"


def test_circle_in_wind_stays_within_ten_percent() -> None:
    worst, _ = _fly_circle(200.0, 0.0, math.pi / 2, 1, 300.0, wind=(0.0, 6.0))
    assert worst < 16.0


def test_altitude_ramp() -> None:
    assert gd.altitude_on_leg(100.0, 200.0, -50.0, 1000.0) == 100.0
    assert gd.altitude_on_leg(100.0, 200.0, 500.0, 1000.0) == 150.0
    assert gd.altitude_on_leg(100.0, 200.0, 5000.0, 1000.0) == 200.0
    assert gd.altitude_on_leg(100.0, 200.0, 0.0, 0.0) == 200.0


def test_switch_distance() -> None:
    r = gd.turn_radius_m(15.0, 0.8 * LIM)
    assert gd.switch_distance_m(0.0, 0.0, 15.0, LIM) == 0.0
    assert abs(gd.switch_distance_m(0.0, math.pi / 2, 15.0, LIM) - r) < 1e-9
    assert abs(gd.switch_distance_m(0.0, -math.pi / 2, 15.0, LIM) - r) < 1e-9
    assert gd.switch_distance_m(0.0, math.pi, 15.0, LIM) == 3.0 * r


def test_angle_travelled_wraps() -> None:
    assert abs(gd.angle_travelled(3.0, -3.0, 1) - (2 * math.pi - 6.0)) < 1e-12
    assert abs(gd.angle_travelled(-3.0, 3.0, -1) - (2 * math.pi - 6.0)) < 1e-12


@given(
    pn=st.floats(-2000, 2000), pe=st.floats(-2000, 2000), vn=st.floats(-25, 25),
    ve=st.floats(-25, 25), radius=st.floats(25, 1000), direction=st.sampled_from([1, -1]),
)  # fmt: skip
def test_circle_outputs_are_bounded_and_consistent(
    pn: float, pe: float, vn: float, ve: float, radius: float, direction: int
) -> None:
    c = gd.follow_circle(pn, pe, vn, ve, (0.0, 0.0), radius, direction, **KW)
    assert abs(c.bank_rad) <= LIM
    assert c.radial_error_m == math.hypot(pn, pe) - radius
    # The tangent course is 90 degrees from the radial direction, on the loiter side.
    radial = math.atan2(pe, pn) if math.hypot(pn, pe) >= 1e-3 else 0.0
    assert abs(gd.wrap_pi(c.course_rad - radial - direction * math.pi / 2)) < 1e-9
