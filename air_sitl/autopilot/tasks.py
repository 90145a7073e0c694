"""Flight tasks: the one thing the aircraft is doing now (idle, take-off, leg, loiter, landing).

A task turns a :class:`Tick` (the vehicle state unpacked once per guidance update) into a
:class:`NavOutput` and says when it is ``done``; the pure math comes from
:mod:`air_sitl.autopilot.guidance`. Which task runs, and in which order, is the sequencer's
business (:mod:`air_sitl.autopilot.sequencer`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from air_sitl.autopilot import guidance
from air_sitl.autopilot.params import GuidanceParams
from air_sitl.autopilot.target import ControlPhase, ControlTarget, control_target
from air_sitl.mission.geometry import Point
from air_sitl.state import VehicleState, positional_builder

NS_PER_S = 1_000_000_000
SETTLE_NS = 10 * NS_PER_S  # tracking counts from 10 s after the turn onto a leg or circle
LIFTOFF_AGL_M = 3.0  # ground roll ends (climb-out begins) above this height
CLIMBOUT_BANK_RAD = math.radians(10.0)
LANDED_SPEED_M_S = 1.0
ALIGN_RAD = math.radians(15.0)  # a leg from "here" is fixed once the course points at its end
ESTABLISHED_COURSE_RAD = math.radians(30.0)  # on a circle: course within this of its tangent
FLARE_PHASE_AGL_M = 8.0  # below this height a landing hands over to the controller's LAND law
_NAN = math.nan


@dataclass(frozen=True, slots=True)
class NavOutput:
    """What the sequencer asks for at one guidance update, and how well the path is tracked."""

    target: ControlTarget
    cross_track_m: float = _NAN
    alt_error_m: float = _NAN
    settled: bool = False


# Built by every leg and circle at 50 Hz, positionally (fields in declared order).
nav_output = positional_builder(NavOutput)
_CRUISE = ControlPhase.CRUISE


class Tick:
    """The inputs of one guidance update, unpacked from the state once."""

    __slots__ = (
        "alt", "course", "course_gs", "gs", "now_ns", "p", "pe", "pn", "speed", "state", "ve",
        "vn",
    )  # fmt: skip

    def __init__(self, state: VehicleState, p: GuidanceParams, speed_m_s: float) -> None:
        self.state = state
        self.p = p
        self.speed = speed_m_s
        self.now_ns = state.sim_time_ns
        self.pn, self.pe = state.pos_ned_m[0], state.pos_ned_m[1]
        self.vn, self.ve = state.vel_ned_m_s[0], state.vel_ned_m_s[1]
        self.alt = state.alt_amsl_m
        self.course_gs = guidance.course_of(self.vn, self.ve, state.yaw_rad)
        self.course, self.gs = self.course_gs


class Task:
    """One thing the aircraft is doing; ``done`` when finished."""

    done: bool = False

    def update(self, t: Tick) -> NavOutput:
        """Guidance for this instant."""
        raise NotImplementedError


class _Tracking:
    """Settling bookkeeping shared by legs and circles."""

    __slots__ = ("alt_ok", "start_ns")

    def __init__(self) -> None:
        self.start_ns: int | None = None
        self.alt_ok = False

    def output(
        self, target: ControlTarget, t: Tick, cross_track_m: float, alt_target_m: float
    ) -> NavOutput:
        alt_error = t.alt - alt_target_m
        if not self.alt_ok and abs(alt_error) <= t.p.alt_acc_m:
            self.alt_ok = True  # a climb or descent onto the segment's altitude has ended
        settled = (
            self.alt_ok and self.start_ns is not None and t.now_ns - self.start_ns >= SETTLE_NS
        )
        return nav_output(target, cross_track_m, alt_error, settled)


def _cruise(t: Tick, bank: float, alt: float, course: float) -> ControlTarget:
    # positional, in ControlTarget's field order (phase, roll, altitude, airspeed, heading,
    # climb-rate limit; the rest their defaults)
    return control_target(_CRUISE, bank, alt, t.speed, course, t.p.climb_max_m_s)


def _split(point: Point) -> tuple[tuple[float, float], float]:
    """A point as its (north, east) in metres and its altitude AMSL."""
    return (point[0], point[1]), point[2]


class IdleTask(Task):
    """On the ground: motor off, brakes on."""

    def update(self, t: Tick) -> NavOutput:
        return NavOutput(
            ControlTarget(
                phase=ControlPhase.IDLE,
                altitude_amsl_m=t.alt,
                airspeed_m_s=0.0,
                heading_rad=t.state.yaw_rad,
            )
        )


class WaitTask(IdleTask):
    """On the ground, motor off, for ``seconds`` (NAV_DELAY before take-off)."""

    def __init__(self, t: Tick, seconds: float) -> None:
        self.end_ns = t.now_ns + round(seconds * NS_PER_S)

    def update(self, t: Tick) -> NavOutput:
        self.done = t.now_ns >= self.end_ns
        return super().update(t)


class TakeoffTask(Task):
    """Runway take-off: ground roll and climb-out on ``course``, then climb to ``alt``."""

    def __init__(self, t: Tick, alt_amsl_m: float, course_rad: float) -> None:
        self.alt = alt_amsl_m
        self.course = course_rad
        self.a = (t.pn, t.pe)
        self.b = (t.pn + 1e5 * math.cos(course_rad), t.pe + 1e5 * math.sin(course_rad))
        self.ground_alt = t.alt - t.state.alt_agl_m
        if t.state.on_ground:
            self.stage = ControlPhase.GROUND_ROLL
        elif t.alt < self._climbout_top(t.p):
            self.stage = ControlPhase.CLIMB
        else:
            self.stage = ControlPhase.CRUISE

    def _climbout_top(self, p: GuidanceParams) -> float:
        height = self.alt - self.ground_alt
        return self.alt - min(p.climbout_diff_m, 0.5 * height)

    def update(self, t: Tick) -> NavOutput:
        p = t.p
        s = t.state
        if (
            self.stage is ControlPhase.GROUND_ROLL
            and not s.on_ground
            and s.alt_agl_m > LIFTOFF_AGL_M
        ):
            self.stage = ControlPhase.CLIMB
        if self.stage is ControlPhase.CLIMB and t.alt >= self._climbout_top(p):
            self.stage = ControlPhase.CRUISE
        height = self.alt - self.ground_alt
        if self.stage is not ControlPhase.GROUND_ROLL and t.alt >= self.alt - min(
            p.alt_acc_m, 0.3 * height
        ):
            self.done = True
        bank_limit = p.bank_limit_rad
        if self.stage is not ControlPhase.CRUISE:
            bank_limit = min(bank_limit, CLIMBOUT_BANK_RAD)
        line = guidance.follow_line(
            t.pn, t.pe, t.vn, t.ve, self.a, self.b,
            period_s=p.l1_period_s, damping=p.l1_damping, bank_limit_rad=bank_limit,
            heading_rad=s.yaw_rad, course_gs=t.course_gs,
        )  # fmt: skip
        heading = self.course
        bank = line.bank_rad
        if self.stage is ControlPhase.GROUND_ROLL:
            # Steer back onto the runway centre line; wings level.
            heading = self.course - max(-0.2, min(0.2, line.cross_track_m / 50.0))
            bank = 0.0
        # positional, in ControlTarget's field order (the rest their defaults), at 50 Hz
        target = control_target(self.stage, bank, self.alt, t.speed, heading, p.climb_max_m_s)
        return nav_output(target)


class LegTask(Task):
    """Follow the leg A->B; done within the acceptance radius, at the turn-anticipation
    distance before B, or once past the perpendicular at B (never circles back).

    ``from_here``: A is where the aircraft is (no previous waypoint: after take-off, a loiter,
    RTL, a jump of the current item). The aircraft first turns toward B; the leg is fixed where
    it points at B within ALIGN_RAD, and tracking counts from there.
    """

    def __init__(
        self,
        t: Tick,
        a: Point,
        b: Point,
        acc_radius_m: float,
        course_out_rad: float | None,
        *,
        from_here: bool = False,
    ) -> None:
        self.a, self.alt_a = _split(a)
        self.b, self.alt_b = _split(b)
        self.acc = acc_radius_m
        self.course_out = course_out_rad
        self.aligning = from_here
        self.track = _Tracking()
        if not from_here:
            self.track.start_ns = t.now_ns

    def update(self, t: Tick) -> NavOutput:
        p = t.p
        if self.aligning:
            self.a = (t.pn, t.pe)
            bearing = math.atan2(self.b[1] - t.pe, self.b[0] - t.pn)
            if abs(guidance.wrap_pi(bearing - t.course)) < ALIGN_RAD:
                self.aligning = False
                self.track.start_ns = t.now_ns
        line = guidance.follow_line(
            t.pn, t.pe, t.vn, t.ve, self.a, self.b,
            period_s=p.l1_period_s, damping=p.l1_damping, bank_limit_rad=p.bank_limit_rad,
            heading_rad=t.state.yaw_rad, course_gs=t.course_gs,
        )  # fmt: skip
        dist_b = math.hypot(self.b[0] - t.pn, self.b[1] - t.pe)
        switch = self.acc
        if self.course_out is not None and line.leg_length_m > 0.0:
            # max(t.gs, t.speed), max(switch, min(half the leg, the turn's distance)) written
            # out (50 Hz), choosing as the builtins do.
            turn_speed = t.speed if t.speed > t.gs else t.gs
            half = 0.5 * line.leg_length_m
            turn = guidance.switch_distance_m(
                line.course_rad, self.course_out, turn_speed, p.bank_limit_rad
            )
            turn = turn if turn < half else half
            switch = turn if turn > switch else switch
        if dist_b <= switch or (
            line.leg_length_m > 0.0 and line.along_track_m >= line.leg_length_m
        ):
            self.done = True
        if self.aligning:
            alt = self.alt_a
            target = _cruise(t, line.bank_rad, alt, line.course_rad)
            return nav_output(target, _NAN, t.alt - alt, False)
        alt = guidance.altitude_on_leg(
            self.alt_a, self.alt_b, line.along_track_m, line.leg_length_m
        )
        target = _cruise(t, line.bank_rad, alt, line.course_rad)
        xtrack = line.cross_track_m if line.leg_length_m > 0.0 else _NAN
        return self.track.output(target, t, xtrack, alt)


class LoiterKind:
    """How a loiter ends."""

    UNLIMITED = "unlimited"
    TURNS = "turns"
    TIME = "time"
    TO_ALT = "to_alt"
    DELAY = "delay"  # NAV_DELAY: hold for ``amount`` seconds from the start of the task


class LoiterTask(Task):
    """Fly to a circle and around it. Turns and time count from the moment the aircraft is
    on the circle (within max(NAV_ACC_RAD, 5% of the radius) of it, flying along it)."""

    def __init__(
        self,
        t: Tick,
        center: Point,
        radius_m: float,
        direction: int,
        kind: str = LoiterKind.UNLIMITED,
        amount: float = 0.0,
    ) -> None:
        self.center, self.alt = _split(center)
        self.radius = radius_m
        self.direction = 1 if direction >= 0 else -1
        self.kind = kind
        self.amount = amount
        self.approach = True
        self.established = False  # on the circle at least once
        self.announced = False  # the sequencer has acted on ``established``
        self.established_ns = 0
        self.swept_rad = 0.0
        self._last_angle = 0.0
        self.track = _Tracking()
        self._approach = LegTask(t, (t.pn, t.pe, t.alt), center, 0.0, None, from_here=True)
        self.start_ns = t.now_ns

    def update(self, t: Tick) -> NavOutput:
        p = t.p
        if self.kind == LoiterKind.DELAY and t.now_ns - self.start_ns >= self.amount * NS_PER_S:
            self.done = True
        dist = math.hypot(t.pn - self.center[0], t.pe - self.center[1])
        l1 = guidance.l1_ratio(p.l1_period_s, p.l1_damping) * max(
            t.gs, guidance.MIN_GUIDANCE_SPEED_M_S
        )
        if self.approach and dist <= self.radius + 2.0 * l1:
            self.approach = False
        if self.approach:
            # A straight leg toward the centre until close enough to capture the circle.
            return self._approach.update(t)
        c = guidance.follow_circle(
            t.pn, t.pe, t.vn, t.ve, self.center, self.radius, self.direction,
            period_s=p.l1_period_s, damping=p.l1_damping, bank_limit_rad=p.bank_limit_rad,
            heading_rad=t.state.yaw_rad, course_gs=t.course_gs,
        )  # fmt: skip
        if not self.established:
            tolerance = max(p.acc_radius_m, 0.05 * self.radius)
            along = abs(guidance.wrap_pi(t.course - c.course_rad)) < ESTABLISHED_COURSE_RAD
            if not c.capturing and along and abs(c.radial_error_m) <= tolerance:
                self.established = True
                self.established_ns = t.now_ns
                self.track.start_ns = t.now_ns
                self._last_angle = c.angle_rad
        else:
            self.swept_rad += guidance.angle_travelled(
                self._last_angle, c.angle_rad, self.direction
            )
            self._last_angle = c.angle_rad
            if self.kind == LoiterKind.TURNS:
                self.done = self.swept_rad >= 2.0 * math.pi * self.amount - 1e-9
            elif self.kind == LoiterKind.TIME:
                self.done = t.now_ns - self.established_ns >= self.amount * NS_PER_S
            elif self.kind == LoiterKind.TO_ALT:
                self.done = abs(t.alt - self.alt) <= p.alt_acc_m
        target = _cruise(t, c.bank_rad, self.alt, c.course_rad)
        if not self.established:
            return nav_output(target, _NAN, t.alt - self.alt, False)
        # Cross-track positive right of the direction of travel, as on a leg (clockwise: the
        # centre is on the right, so outside the circle is negative).
        return self.track.output(target, t, -self.direction * c.radial_error_m, self.alt)


class LandTask(Task):
    """Approach along A->touchdown on the FW_LND_ANG glide slope, touch down, roll out.

    ``ground_amsl_m`` is the ground at the touchdown point (the DEM's with ``--dem``, else
    home's): the approach hands over to the flare, and the flare judges its height, above it.
    """

    def __init__(self, a: Point, touchdown: Point, ground_amsl_m: float) -> None:
        self.a, self.alt_a = _split(a)
        self.td, self.td_alt = _split(touchdown)
        self.ground_m = ground_amsl_m
        self.touched = False

    @classmethod
    def ahead(cls, t: Tick, ground_amsl_m: float) -> LandTask:
        """Glide straight ahead to a touchdown point on the FW_LND_ANG slope."""
        agl = max(0.0, t.alt - ground_amsl_m)
        dist = max(50.0, agl / math.tan(t.p.land_angle_rad))
        c = t.course
        td = (t.pn + dist * math.cos(c), t.pe + dist * math.sin(c), ground_amsl_m)
        return cls((t.pn, t.pe, t.alt), td, ground_amsl_m)

    def update(self, t: Tick) -> NavOutput:
        p = t.p
        s = t.state
        line = guidance.follow_line(
            t.pn, t.pe, t.vn, t.ve, self.a, self.td,
            period_s=p.l1_period_s, damping=p.l1_damping, bank_limit_rad=p.bank_limit_rad,
            heading_rad=s.yaw_rad, course_gs=t.course_gs,
        )  # fmt: skip
        if s.on_ground:
            self.touched = True
        to_go = line.leg_length_m - line.along_track_m
        slope_alt = self.td_alt + max(0.0, to_go) * math.tan(p.land_angle_rad)
        alt = min(slope_alt, self.alt_a)
        if self.touched:
            self.done = t.gs < LANDED_SPEED_M_S
            phase = ControlPhase.LAND
            bank = 0.0
        else:
            # TECS flies the glide slope down to flare height; the LAND law flares.
            height = s.alt_amsl_m - self.ground_m
            phase = ControlPhase.LAND if height < FLARE_PHASE_AGL_M else ControlPhase.CRUISE
            bank = line.bank_rad
        on_slope = slope_alt <= self.alt_a + 1.0
        target = ControlTarget(
            phase=phase,
            roll_rad=bank,
            altitude_amsl_m=alt,
            airspeed_m_s=p.clamp_speed(p.land_airspeed_m_s) if on_slope else t.speed,
            heading_rad=line.course_rad,
            climb_rate_limit_m_s=p.sink_max_m_s,
            ground_amsl_m=self.ground_m,
        )
        return NavOutput(target)
