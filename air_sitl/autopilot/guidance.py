"""Lateral and vertical guidance: pure math in the local NED frame (north, east; metres).

L1 path following as in PX4's ``ECL_L1_Pos_Controller`` and ArduPilot's ``AP_L1_Control``
(Park, Deyst, How: "A New Nonlinear Guidance Logic for Trajectory Tracking", 2004): the aircraft
steers toward a reference point on the path one L1 distance ahead, with lateral acceleration
``a = 4 zeta^2 V^2 / L1 * sin(eta)``; for circles a PD law on the radial error plus the
centripetal term, with ArduPilot's switch-over from "capture" (head for the centre) to "circle".
Bank angles come from coordinated-turn physics ``tan(phi) = a / g``. Positive lateral
acceleration, bank and cross-track error mean "to the right".
"""

from __future__ import annotations

import math
from typing import NamedTuple

GRAVITY_M_S2 = 9.80665
_SIN_45 = math.sqrt(0.5)
_HALF_PI = 0.5 * math.pi
_TWO_PI = 2.0 * math.pi
MIN_GUIDANCE_SPEED_M_S = 5.0  # below this (on the ground) L1 uses this speed for its distance
_tuple_new = tuple.__new__  # what a NamedTuple's __new__ calls, without its Python frame


class LineTracking(NamedTuple):
    """Result of following the line through A toward B."""

    bank_rad: float
    cross_track_m: float  # signed distance from the line, positive right of A->B
    along_track_m: float  # distance from A along A->B (negative behind A)
    leg_length_m: float
    course_rad: float  # course of A->B, 0 north, clockwise positive


class CircleTracking(NamedTuple):
    """Result of following a loiter circle."""

    bank_rad: float
    radial_error_m: float  # distance from the centre minus the radius (positive outside)
    angle_rad: float  # position angle around the centre: 0 north, clockwise positive
    capturing: bool  # still heading for the circle rather than flying along it
    course_rad: float  # course of the circle tangent at the aircraft's angle


def wrap_pi(angle_rad: float) -> float:
    """Wrap an angle into [-pi, pi)."""
    return (angle_rad + math.pi) % _TWO_PI - math.pi


def l1_ratio(period_s: float, damping: float) -> float:
    """L1 distance per m/s of ground speed (PX4: period * damping / pi)."""
    return period_s * damping / math.pi


def bank_for_accel(lateral_accel_m_s2: float, bank_limit_rad: float) -> float:
    """Coordinated-turn bank for a lateral acceleration, within +-bank_limit."""
    bank = math.atan(lateral_accel_m_s2 / GRAVITY_M_S2)
    if bank > bank_limit_rad:
        return bank_limit_rad
    if bank < -bank_limit_rad:
        return -bank_limit_rad
    return bank


def course_of(vn: float, ve: float, fallback_rad: float) -> tuple[float, float]:
    """(ground course, ground speed); the fallback course below 1 m/s (standing still)."""
    gs = math.hypot(vn, ve)
    if gs < 1.0:
        return fallback_rad, gs
    return math.atan2(ve, vn), gs


def follow_line(
    pn: float,
    pe: float,
    vn: float,
    ve: float,
    a: tuple[float, float],
    b: tuple[float, float],
    *,
    period_s: float,
    damping: float,
    bank_limit_rad: float,
    heading_rad: float = 0.0,
    course_gs: tuple[float, float] | None = None,
) -> LineTracking:
    """L1 bank command to follow the line A->B from position (pn, pe) at ground velocity.

    Far behind A (more than L1 away and more than 45 degrees off the line's direction) the
    aircraft heads for A first, as PX4 does; otherwise it intercepts the line at up to 45
    degrees. ``heading_rad`` stands in for the ground course when hardly moving.
    ``course_gs``: :func:`course_of` the velocity and heading, when the caller has it.
    """
    dn = b[0] - a[0]
    de = b[1] - a[1]
    leg = math.hypot(dn, de)
    chi_v, gs = course_gs if course_gs is not None else course_of(vn, ve, heading_rad)
    speed = gs if gs > MIN_GUIDANCE_SPEED_M_S else MIN_GUIDANCE_SPEED_M_S
    l1 = period_s * damping / math.pi * speed  # l1_ratio written out (50 Hz)
    rn = pn - a[0]
    re = pe - a[1]
    if leg < 1e-6:
        # Degenerate leg: fly straight to the point.
        course = math.atan2(-re, -rn)
        un, ue = math.cos(course), math.sin(course)
        leg = 0.0
    else:
        un, ue = dn / leg, de / leg
        course = math.atan2(ue, un)
    xtrack = un * re - ue * rn
    along = un * rn + ue * re
    dist_a = math.hypot(rn, re)
    if leg > 0.0 and dist_a > l1 and along < -_SIN_45 * dist_a:
        chi_ref = math.atan2(-re, -rn)  # head back to A first
    else:
        s = xtrack / l1
        s = _SIN_45 if s > _SIN_45 else (-_SIN_45 if s < -_SIN_45 else s)
        chi_ref = course - math.asin(s)
    eta = (chi_ref - chi_v + math.pi) % _TWO_PI - math.pi  # wrap_pi written out (50 Hz)
    eta = _HALF_PI if eta > _HALF_PI else (-_HALF_PI if eta < -_HALF_PI else eta)
    accel = 4.0 * damping * damping * speed * speed / l1 * math.sin(eta)
    # LineTracking(bank_for_accel(...), ...) written out (50 Hz): the tuple NamedTuple's
    # __new__ makes, the bank as bank_for_accel clamps it.
    bank = math.atan(accel / GRAVITY_M_S2)
    if bank > bank_limit_rad:
        bank = bank_limit_rad
    elif bank < -bank_limit_rad:
        bank = -bank_limit_rad
    return _tuple_new(LineTracking, (bank, xtrack, along, leg, course))


def follow_circle(
    pn: float,
    pe: float,
    vn: float,
    ve: float,
    center: tuple[float, float],
    radius_m: float,
    direction: int,
    *,
    period_s: float,
    damping: float,
    bank_limit_rad: float,
    heading_rad: float = 0.0,
    course_gs: tuple[float, float] | None = None,
) -> CircleTracking:
    """L1 loiter: bank command to circle ``center`` at ``radius_m``.

    ``direction`` +1 is clockwise seen from above (north -> east), -1 counter-clockwise.
    ArduPilot's ``update_loiter``: outside the circle the aircraft heads for the centre
    ("capture") until the circle law asks for the sharper turn, then flies the circle with a
    PD law on the radial error plus the centripetal acceleration of the tangential speed.
    ``course_gs``: :func:`course_of` the velocity and heading, when the caller has it.
    """
    rn = pn - center[0]
    re = pe - center[1]
    dist = math.hypot(rn, re)
    if dist < 1e-3:
        urn, ure = 1.0, 0.0
    else:
        urn, ure = rn / dist, re / dist
    chi_v, gs = course_gs if course_gs is not None else course_of(vn, ve, heading_rad)
    speed = gs if gs > MIN_GUIDANCE_SPEED_M_S else MIN_GUIDANCE_SPEED_M_S
    l1 = period_s * damping / math.pi * speed  # l1_ratio written out (50 Hz)
    omega = _TWO_PI / period_s
    # Capture: L1 toward the centre.
    nu = wrap_pi(math.atan2(-ure, -urn) - chi_v)
    nu = _HALF_PI if nu > _HALF_PI else (-_HALF_PI if nu < -_HALF_PI else nu)
    accel_capture = 4.0 * damping * damping * speed * speed / l1 * math.sin(nu)
    # Circle: PD on the radial error, plus centripetal.
    radial_error = dist - radius_m
    v_radial = vn * urn + ve * ure  # outward
    v_tangent = direction * (ve * urn - vn * ure)  # along the loiter direction
    accel_pd = radial_error * omega * omega + v_radial * 2.0 * damping * omega
    if v_radial > 0.0 and v_tangent < 0.0 and accel_pd < 0.0:
        accel_pd = 0.0
    accel_ctr = v_tangent * v_tangent / max(0.5 * radius_m, radius_m + radial_error)
    accel_circle = direction * (accel_pd + accel_ctr)
    capturing = radial_error > 0.0 and direction * accel_capture < direction * accel_circle
    accel = accel_capture if capturing else accel_circle
    angle = math.atan2(ure, urn)
    course = angle + direction * _HALF_PI
    bank = math.atan(accel / GRAVITY_M_S2)  # bank_for_accel written out (50 Hz)
    if bank > bank_limit_rad:
        bank = bank_limit_rad
    elif bank < -bank_limit_rad:
        bank = -bank_limit_rad
    course = (course + math.pi) % _TWO_PI - math.pi  # wrap_pi
    return _tuple_new(CircleTracking, (bank, radial_error, angle, capturing, course))


def altitude_on_leg(
    alt_a_m: float, alt_b_m: float, along_track_m: float, leg_length_m: float
) -> float:
    """Planned altitude at a point of the leg: a straight ramp from A's to B's altitude."""
    if leg_length_m <= 1e-6:
        return alt_b_m
    f = along_track_m / leg_length_m
    f = 0.0 if f < 0.0 else (1.0 if f > 1.0 else f)
    return alt_a_m + (alt_b_m - alt_a_m) * f


def turn_radius_m(speed_m_s: float, bank_rad: float) -> float:
    """Radius of a level coordinated turn."""
    return speed_m_s * speed_m_s / (GRAVITY_M_S2 * math.tan(bank_rad))


def switch_distance_m(
    course_in_rad: float, course_out_rad: float, speed_m_s: float, bank_limit_rad: float
) -> float:
    """How far before a waypoint to start the turn onto the next leg so as to roll out on it.

    The tangent point of a turn at 80% of the bank limit: ``R * tan(turn / 2)``, capped at
    three turn radii for near-reversals.
    """
    # wrap_pi, turn_radius_m, max and min written out (50 Hz), choosing as the builtins do.
    turn = abs((course_out_rad - course_in_rad + math.pi) % _TWO_PI - math.pi)
    speed = MIN_GUIDANCE_SPEED_M_S if speed_m_s < MIN_GUIDANCE_SPEED_M_S else speed_m_s
    radius = speed * speed / (GRAVITY_M_S2 * math.tan(0.8 * bank_limit_rad))
    if turn >= 0.8 * math.pi:
        return 3.0 * radius
    ahead = radius * math.tan(0.5 * turn)
    return ahead if ahead < 3.0 * radius else 3.0 * radius


def angle_travelled(previous_rad: float, current_rad: float, direction: int) -> float:
    """Angle swept around a centre from ``previous`` to ``current`` in ``direction``."""
    return direction * wrap_pi(current_rad - previous_rad)
