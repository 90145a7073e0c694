"""The mission state machine: modes, mission items, capture window, and what to fly now.

:class:`MissionExecutor` turns a :class:`~air_sitl.mission.items.Mission` and the vehicle state
into a :class:`~air_sitl.autopilot.target.ControlTarget`. It runs one navigation *task* at a
time (take-off, leg, loiter, landing, idle on the ground); tasks use the pure math of
:mod:`air_sitl.autopilot.guidance`. Sequencing follows PX4: DO_* items run when reached,
DO_JUMP's counter is on the jump item (taken while ``count < repeat``), the aircraft loiters at
the last waypoint when a mission ends, RTL climbs (never descends) to RTL_RETURN_ALT and loiters
at home.

- ``mission_completed``: the last navigation item is done (a final RTL or LOITER_UNLIM once the
  aircraft is established on its circle; a final NAV_LAND once stopped on the ground).
- Capture window: IMAGE_START_CAPTURE .. IMAGE_STOP_CAPTURE when the plan has either; otherwise
  (AIR's rule) from reaching the first positioned item after take-off, at its altitude, to
  ``mission_completed``.
- Airspeed: DO_CHANGE_SPEED (an airspeed, or a ground speed flown with the estimated wind),
  else the plan's cruise speed in MISSION mode, else FW_AIRSPD_TRIM; always within
  FW_AIRSPD_MIN..MAX.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

from air_sitl.autopilot import guidance
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.target import ControlPhase, ControlTarget
from air_sitl.errors import PlanError
from air_sitl.frames import geodetic2ned
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem, MissionType
from air_sitl.mission.validate import check_mission
from air_sitl.state import FlightMode, GeoPoint, VehicleState

NS_PER_S = 1_000_000_000
SETTLE_NS = 10 * NS_PER_S  # tracking counts from 10 s after the turn onto a leg or circle
LIFTOFF_AGL_M = 3.0  # ground roll ends (climb-out begins) above this height
CLIMBOUT_BANK_RAD = math.radians(10.0)
LANDED_SPEED_M_S = 1.0
ALIGN_RAD = math.radians(15.0)  # a leg from "here" is fixed once the course points at its end
ESTABLISHED_COURSE_RAD = math.radians(30.0)  # on a circle: course within this of its tangent
FLARE_PHASE_AGL_M = 8.0  # below this height a landing hands over to the controller's LAND law
WIND_FILTER_GAIN = 0.02  # per 50 Hz guidance update: about a 1 s time constant
# Mission start refused when its first positioned item is farther than this from home.
MAX_FIRST_WAYPOINT_DISTANCE_M = 100_000.0
_NAN = math.nan
_LOITERS = frozenset(
    {
        MavCmd.NAV_LOITER_UNLIM,
        MavCmd.NAV_LOITER_TURNS,
        MavCmd.NAV_LOITER_TIME,
        MavCmd.NAV_LOITER_TO_ALT,
    }
)
_POSITIONED = _LOITERS | {MavCmd.NAV_WAYPOINT}
_RELATIVE_FRAMES = frozenset({MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT})
MAX_PENDING = 1000  # events and reached items kept for a reader that does not come
_MAX_DO_STEPS = 10_000  # DO_JUMP chains with no navigation item in between end the mission

Point = tuple[float, float, float]  # north m, east m, altitude AMSL m


@dataclass(frozen=True, slots=True)
class NavParams:
    """The parameters guidance needs, converted to SI units once per change."""

    trim_m_s: float
    min_m_s: float
    max_m_s: float
    bank_limit_rad: float
    l1_period_s: float
    l1_damping: float
    acc_radius_m: float
    alt_acc_m: float
    loiter_radius_m: float
    climb_max_m_s: float
    sink_max_m_s: float
    climbout_diff_m: float
    takeoff_alt_m: float
    rtl_alt_m: float
    land_angle_rad: float
    land_airspeed_m_s: float

    @classmethod
    def from_store(cls, p: ParamStore) -> NavParams:
        """Snapshot of the store."""
        lo = p.get("FW_AIRSPD_MIN")
        return cls(
            trim_m_s=p.get("FW_AIRSPD_TRIM"),
            min_m_s=lo,
            max_m_s=max(lo, p.get("FW_AIRSPD_MAX")),
            bank_limit_rad=math.radians(p.get("FW_R_LIM")),
            l1_period_s=p.get("NAV_L1_PERIOD"),
            l1_damping=p.get("NAV_L1_DAMPING"),
            acc_radius_m=p.get("NAV_ACC_RAD"),
            alt_acc_m=p.get("NAV_FW_ALT_RAD"),
            loiter_radius_m=p.get("NAV_LOITER_RAD"),
            climb_max_m_s=p.get("FW_T_CLMB_MAX"),
            sink_max_m_s=p.get("FW_T_SINK_MAX"),
            climbout_diff_m=p.get("FW_CLMBOUT_DIFF"),
            takeoff_alt_m=p.get("MIS_TAKEOFF_ALT"),
            rtl_alt_m=p.get("RTL_RETURN_ALT"),
            land_angle_rad=math.radians(p.get("FW_LND_ANG")),
            land_airspeed_m_s=p.get("FW_LND_AIRSPD"),
        )

    def clamp_speed(self, speed_m_s: float) -> float:
        """Airspeed within [FW_AIRSPD_MIN, FW_AIRSPD_MAX]."""
        return min(self.max_m_s, max(self.min_m_s, speed_m_s))


@dataclass(frozen=True, slots=True)
class NavOutput:
    """What the executor asks for at one guidance update, and how well the path is tracked."""

    target: ControlTarget
    cross_track_m: float = _NAN
    alt_error_m: float = _NAN
    settled: bool = False


class Tick:
    """The inputs of one guidance update, unpacked from the state once."""

    __slots__ = ("alt", "course", "gs", "now_ns", "p", "pe", "pn", "speed", "state", "ve", "vn")

    def __init__(self, state: VehicleState, p: NavParams, speed_m_s: float) -> None:
        self.state = state
        self.p = p
        self.speed = speed_m_s
        self.now_ns = state.sim_time_ns
        self.pn, self.pe = state.pos_ned_m[0], state.pos_ned_m[1]
        self.vn, self.ve = state.vel_ned_m_s[0], state.vel_ned_m_s[1]
        self.alt = state.alt_amsl_m
        self.course, self.gs = guidance.course_of(self.vn, self.ve, state.yaw_rad)


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
        return NavOutput(target, cross_track_m, alt_error, settled)


def _cruise(t: Tick, bank: float, alt: float, course: float) -> ControlTarget:
    return ControlTarget(
        phase=ControlPhase.CRUISE,
        roll_rad=bank,
        altitude_amsl_m=alt,
        airspeed_m_s=t.speed,
        heading_rad=course,
        climb_rate_limit_m_s=t.p.climb_max_m_s,
    )


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

    def _climbout_top(self, p: NavParams) -> float:
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
            heading_rad=s.yaw_rad,
        )  # fmt: skip
        heading = self.course
        bank = line.bank_rad
        if self.stage is ControlPhase.GROUND_ROLL:
            # Steer back onto the runway centre line; wings level.
            heading = self.course - max(-0.2, min(0.2, line.cross_track_m / 50.0))
            bank = 0.0
        target = ControlTarget(
            phase=self.stage,
            roll_rad=bank,
            altitude_amsl_m=self.alt,
            airspeed_m_s=t.speed,
            heading_rad=heading,
            climb_rate_limit_m_s=p.climb_max_m_s,
        )
        return NavOutput(target)


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
        self.a = (a[0], a[1])
        self.alt_a = a[2]
        self.b = (b[0], b[1])
        self.alt_b = b[2]
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
            heading_rad=t.state.yaw_rad,
        )  # fmt: skip
        dist_b = math.hypot(self.b[0] - t.pn, self.b[1] - t.pe)
        switch = self.acc
        if self.course_out is not None and line.leg_length_m > 0.0:
            turn_speed = max(t.gs, t.speed)
            switch = max(
                switch,
                min(
                    0.5 * line.leg_length_m,
                    guidance.switch_distance_m(
                        line.course_rad, self.course_out, turn_speed, p.bank_limit_rad
                    ),
                ),
            )
        if dist_b <= switch or (
            line.leg_length_m > 0.0 and line.along_track_m >= line.leg_length_m
        ):
            self.done = True
        if self.aligning:
            alt = self.alt_a
            target = _cruise(t, line.bank_rad, alt, line.course_rad)
            return NavOutput(target, _NAN, t.alt - alt, False)
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
        self.center = (center[0], center[1])
        self.alt = center[2]
        self.radius = radius_m
        self.direction = 1 if direction >= 0 else -1
        self.kind = kind
        self.amount = amount
        self.approach = True
        self.established = False  # on the circle at least once
        self.announced = False  # the executor has acted on ``established``
        self.established_ns = 0
        self.swept_rad = 0.0
        self._last_angle = 0.0
        self.track = _Tracking()
        self._approach = LegTask(t, (t.pn, t.pe, t.alt), center, 0.0, None, from_here=True)

    def update(self, t: Tick) -> NavOutput:
        p = t.p
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
            heading_rad=t.state.yaw_rad,
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
            return NavOutput(target, _NAN, t.alt - self.alt, False)
        return self.track.output(target, t, c.radial_error_m, self.alt)


class LandTask(Task):
    """Approach along A->touchdown on the FW_LND_ANG glide slope, touch down, roll out."""

    def __init__(self, a: Point, touchdown: Point) -> None:
        self.a = (a[0], a[1])
        self.alt_a = a[2]
        self.td = (touchdown[0], touchdown[1])
        self.td_alt = touchdown[2]
        self.touched = False

    def update(self, t: Tick) -> NavOutput:
        p = t.p
        s = t.state
        line = guidance.follow_line(
            t.pn, t.pe, t.vn, t.ve, self.a, self.td,
            period_s=p.l1_period_s, damping=p.l1_damping, bank_limit_rad=p.bank_limit_rad,
            heading_rad=s.yaw_rad,
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
            phase = ControlPhase.LAND if s.alt_agl_m < FLARE_PHASE_AGL_M else ControlPhase.CRUISE
            bank = line.bank_rad
        on_slope = slope_alt <= self.alt_a + 1.0
        target = ControlTarget(
            phase=phase,
            roll_rad=bank,
            altitude_amsl_m=alt,
            airspeed_m_s=p.clamp_speed(p.land_airspeed_m_s) if on_slope else t.speed,
            heading_rad=line.course_rad,
            climb_rate_limit_m_s=p.sink_max_m_s,
        )
        return NavOutput(target)


def item_altitude_amsl(item: MissionItem, home: GeoPoint) -> float:
    """Altitude of a positioned item above mean sea level (relative frames add home's)."""
    if item.frame in _RELATIVE_FRAMES:
        return home.alt_amsl_m + item.alt_m
    return item.alt_m


def item_point(item: MissionItem, home: GeoPoint) -> Point:
    """Position of an item in home's NED frame; NaN north/east when it has none (0, 0)."""
    alt = item_altitude_amsl(item, home)
    if (item.lat_deg == 0.0 and item.lon_deg == 0.0) or not (
        math.isfinite(item.lat_deg) and math.isfinite(item.lon_deg)
    ):
        return (_NAN, _NAN, alt)
    n, e, _ = geodetic2ned(
        item.lat_deg, item.lon_deg, alt, home.lat_deg, home.lon_deg, home.alt_amsl_m
    )
    return (n, e, alt)


def loiter_geometry(item: MissionItem, default_radius_m: float) -> tuple[float, int]:
    """(radius, direction) of a loiter item; radius param sign: positive = clockwise."""
    raw = item.param2 if item.command == MavCmd.NAV_LOITER_TO_ALT else item.param3
    if not math.isfinite(raw) or abs(raw) < 1.0:
        return default_radius_m, 1
    return abs(raw), (1 if raw > 0 else -1)


def first_flown_item(mission: Mission) -> int:
    """Index of the first positioned navigation item after take-off (-1 if none).

    This is the "start point" of AIR: where ``--air-start`` places the aircraft and where the
    default capture window begins.
    """
    items = mission.items
    start = 0
    for i, item in enumerate(items):
        if item.command == MavCmd.NAV_TAKEOFF:
            start = i + 1
            break
    for i in range(start, len(items)):
        if items[i].command in _POSITIONED:
            return i
    return -1


def next_nav_index(items: tuple[MissionItem, ...], seq: int, jump_counts: dict[int, int]) -> int:
    """Index of the navigation item reached from ``seq`` onward (DO_JUMPs followed, counting
    in ``jump_counts``, which is updated); -1 at the end of the mission."""
    steps = 0
    n = len(items)
    while 0 <= seq < n:
        item = items[seq]
        if item.is_nav:
            return seq
        if item.command == MavCmd.DO_JUMP:
            count = jump_counts.get(seq, 0)
            if count < item.param2:
                jump_counts[seq] = count + 1
                seq = int(item.param1)
            else:
                seq += 1
        else:
            seq += 1
        steps += 1
        if steps > _MAX_DO_STEPS:
            return -1
    return -1


def validate_mission(mission: Mission) -> None:
    """Raise :class:`PlanError` when the executor cannot fly ``mission`` (empty is allowed)."""
    problem = check_mission(mission.items, MissionType.MISSION, allow_empty=True)
    if problem is not None:
        where = "mission" if problem.index < 0 else f"item {problem.index}"
        msg = f"{mission.source}: {where}: {problem.message}"
        raise PlanError(msg)


class MissionExecutor:
    """Modes, arming, mission sequencing and the capture window; one :class:`Task` at a time.

    Everything runs on the simulation thread. Commands return ``(accepted, reason)``.
    """

    def __init__(self, mission: Mission, home: GeoPoint, params: ParamStore) -> None:
        self.home = home
        self.params = params
        self._np_version = -1
        self._np = NavParams.from_store(params)
        self.mode = FlightMode.IDLE
        self.armed = False
        self.capturing = False
        self.mission_completed = False
        self.current_seq = -1
        self._task: Task = IdleTask()
        self._tick: Tick | None = None
        self._state: VehicleState | None = None
        self._events: list[str] = []
        self._reached: list[int] = []
        # Reached items not yet shown in an AutopilotStatus (the facade shows one per step).
        self.reached_queue: deque[int] = deque()
        self._speed_override: float | None = None
        self._ground_speed_mode = False  # DO_CHANGE_SPEED asked for a ground speed
        self._wind_ne = (0.0, 0.0)  # wind estimate (ground minus air velocity), low-passed
        self._after_takeoff_seq = -1  # mission item to enter after an implicit take-off
        self._in_mission = False  # flying mission items (as opposed to waiting on the ground)
        self._deferred: Callable[[], None] | None = None  # a command that needs a state first
        self._set_mission_fields(mission)

    # ----------------------------------------------------------------------------- mission
    def _set_mission_fields(self, mission: Mission) -> None:
        validate_mission(mission)
        self.mission = mission
        self._items = mission.items
        self._points = [item_point(item, self.home) for item in mission.items]
        self._jump_counts: dict[int, int] = {}
        self._prev_point: Point | None = None
        self._has_capture_items = any(
            item.command in (MavCmd.IMAGE_START_CAPTURE, MavCmd.IMAGE_STOP_CAPTURE)
            for item in mission.items
        )
        self._first_flown = first_flown_item(mission)
        self._default_capture_pending = False
        self._default_capture_done = False
        self._last_nav_seq = max(
            (i for i, item in enumerate(mission.items) if item.is_nav), default=-1
        )
        self.current_seq = 0 if mission.items else -1
        self.mission_completed = False

    def set_mission(self, mission: Mission) -> None:
        """Replace the mission (PX4-like: allowed on the ground and in flight).

        In MISSION mode in the air the new mission is flown from its first item.
        """
        self._set_mission_fields(mission)
        self._speed_override = None  # the new plan's speeds apply
        self._ground_speed_mode = False
        self._emit(f"Mission replaced: {len(mission.items)} items")
        if self.mode is FlightMode.MISSION and self._in_mission and self._state is not None:
            if mission.items:
                self._enter_item(0)
            else:
                self._hold_here("Mission cleared: holding")

    # ------------------------------------------------------------------------------ events
    def _emit(self, text: str) -> None:
        self._events.append(text)
        if len(self._events) > MAX_PENDING:
            del self._events[0]  # nobody is reading them (the fly command)

    def pop_events(self) -> list[str]:
        """STATUSTEXT-style messages since the last call, oldest first."""
        events, self._events = self._events, []
        return events

    def _mark_reached(self, seq: int) -> None:
        self._reached.append(seq)
        if len(self._reached) > MAX_PENDING:
            del self._reached[0]
        self.reached_queue.append(seq)

    def pop_reached(self) -> list[int]:
        """Navigation items reached since the last call (MISSION_ITEM_REACHED), oldest first."""
        reached, self._reached = self._reached, []
        return reached

    # ------------------------------------------------------------------------------ update
    @property
    def nav_params(self) -> NavParams:
        """Current parameters, re-read when the store changed."""
        if self.params.version != self._np_version:
            self._np = NavParams.from_store(self.params)
            self._np_version = self.params.version
        return self._np

    def _speed(self, p: NavParams, course_rad: float = 0.0) -> float:
        if self._speed_override is not None:
            if not self._ground_speed_mode:
                return p.clamp_speed(self._speed_override)
            # Airspeed that makes the ground speed along the current course the one asked for.
            wn, we = self._wind_ne
            c, s = math.cos(course_rad), math.sin(course_rad)
            along = wn * c + we * s
            across = we * c - wn * s
            return p.clamp_speed(math.hypot(self._speed_override - along, across))
        plan = self.mission.cruise_speed_m_s
        if self.mode is FlightMode.MISSION and math.isfinite(plan) and plan > 0.0:
            return p.clamp_speed(plan)
        return p.clamp_speed(p.trim_m_s)

    def _estimate_wind(self, state: VehicleState) -> None:
        """Wind = ground velocity - air velocity (truth airspeed along the heading), low-passed."""
        if state.on_ground:
            return
        v_air = state.airspeed_m_s * math.cos(state.pitch_rad)
        wn = state.vel_ned_m_s[0] - v_air * math.cos(state.yaw_rad)
        we = state.vel_ned_m_s[1] - v_air * math.sin(state.yaw_rad)
        k = WIND_FILTER_GAIN
        self._wind_ne = (
            self._wind_ne[0] + k * (wn - self._wind_ne[0]),
            self._wind_ne[1] + k * (we - self._wind_ne[1]),
        )

    def update(self, state: VehicleState) -> NavOutput:
        """Advance the state machine and return guidance for ``state``."""
        self._state = state
        p = self.nav_params
        if self._deferred is not None:
            deferred, self._deferred = self._deferred, None
            deferred()
        if self._ground_speed_mode:
            self._estimate_wind(state)
        tick = self._tick = self._tick_now()
        out = self._task.update(tick)
        # Tasks may finish several in a row (a waypoint, then DO items): bounded by the items.
        for _ in range(len(self._items) + 4):
            if not self._task.done:
                break
            self._task_done()
            tick.speed = self._speed(p, tick.course)
            out = self._task.update(tick)
        task = self._task
        if isinstance(task, LoiterTask) and task.established and not task.announced:
            self._on_established(task)
        if self._default_capture_pending and (
            abs(state.alt_amsl_m - self._points[self._first_flown][2]) <= p.alt_acc_m
        ):
            self._default_capture_pending = False
            self._set_capture(True)
        return out

    def _tick_now(self) -> Tick:
        """A tick for the last state (commands create tasks between updates)."""
        assert self._state is not None
        p = self.nav_params
        tick = Tick(self._state, p, 0.0)
        tick.speed = self._speed(p, tick.course)
        return tick

    # ------------------------------------------------------------------------- sequencing
    def _enter_item(self, seq: int) -> None:
        """Make ``seq`` current: run DO items from there, then start the next navigation item."""
        self._in_mission = True
        self.mission_completed = False
        steps = 0
        items = self._items
        while 0 <= seq < len(items):
            item = items[seq]
            if item.is_nav:
                self.current_seq = seq
                self._start_nav_item(seq)
                return
            steps += 1
            if steps > _MAX_DO_STEPS:
                self._emit("Mission: DO_JUMP loop without navigation items")
                break
            self.current_seq = seq
            seq = self._run_do_item(seq)
        self._finish_mission()

    def _run_do_item(self, seq: int) -> int:
        """Execute one DO item; return the index to continue with."""
        item = self._items[seq]
        cmd = item.command
        if cmd == MavCmd.DO_JUMP:
            count = self._jump_counts.get(seq, 0)
            if count < item.param2:
                self._jump_counts[seq] = count + 1
                target = int(item.param1)
                self._emit(f"Jump to item {target} ({count + 1}/{int(item.param2)})")
                return target
            return seq + 1
        if cmd == MavCmd.DO_CHANGE_SPEED:
            if item.param1 in (0.0, 1.0) and item.param2 > 0.0:
                self._speed_override = item.param2
                self._ground_speed_mode = item.param1 == 1.0
                kind = "ground" if self._ground_speed_mode else "air"
                self._emit(f"Speed set to {item.param2:g} m/s ({kind})")
        elif cmd == MavCmd.IMAGE_START_CAPTURE:
            self._set_capture(True)
        elif cmd == MavCmd.IMAGE_STOP_CAPTURE:
            self._set_capture(False)
        return seq + 1

    def _start_nav_item(self, seq: int) -> None:
        item = self._items[seq]
        t = self._tick_now()
        p = t.p
        here: Point = (t.pn, t.pe, t.alt)
        n, e, alt = self._points[seq]
        if math.isnan(n):
            n, e = t.pn, t.pe
        if math.isnan(alt):
            alt = t.alt
        point: Point = (n, e, alt)
        cmd = item.command
        if cmd == MavCmd.NAV_TAKEOFF:
            self._task = TakeoffTask(t, alt, self._runway_course(seq, t))
            self._emit(f"Takeoff to {alt - self.home.alt_amsl_m:.0f} m")
        elif cmd == MavCmd.NAV_WAYPOINT:
            if t.state.on_ground:
                self._implicit_takeoff(seq)
                return
            acc = (
                item.param2 if math.isfinite(item.param2) and item.param2 > 0.0 else p.acc_radius_m
            )
            prev = self._prev_point if self._prev_point is not None else here
            self._task = LegTask(
                t, prev, point, acc, self._course_out(seq, point),
                from_here=self._prev_point is None,
            )  # fmt: skip
        elif cmd in _LOITERS:
            if t.state.on_ground:
                self._implicit_takeoff(seq)
                return
            radius, direction = loiter_geometry(item, p.loiter_radius_m)
            kind = {
                MavCmd.NAV_LOITER_UNLIM: LoiterKind.UNLIMITED,
                MavCmd.NAV_LOITER_TURNS: LoiterKind.TURNS,
                MavCmd.NAV_LOITER_TIME: LoiterKind.TIME,
                MavCmd.NAV_LOITER_TO_ALT: LoiterKind.TO_ALT,
            }[MavCmd(cmd)]
            amount = item.param1 if kind in (LoiterKind.TURNS, LoiterKind.TIME) else 0.0
            self._task = LoiterTask(t, point, radius, direction, kind, amount)
        elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            if t.state.on_ground:
                self._complete_item(seq)
                return
            self._start_rtl(t)
        elif cmd == MavCmd.NAV_LAND:
            if t.state.on_ground:
                self._complete_item(seq)
                return
            ground = self.home.alt_amsl_m
            if math.isnan(self._points[seq][0]):
                self._task = self._land_ahead(t)
            else:
                prev = self._prev_point if self._prev_point is not None else here
                self._task = LandTask(prev, (n, e, max(ground, min(alt, ground + 1.0))))
            self._emit("Landing")

    def _implicit_takeoff(self, seq: int) -> None:
        """A mission started on the ground without a take-off item climbs out first."""
        t = self._tick_now()
        self._after_takeoff_seq = seq
        alt = self.home.alt_amsl_m + t.p.takeoff_alt_m
        self._task = TakeoffTask(t, alt, self._runway_course(seq - 1, t))
        self._emit(f"Takeoff to {t.p.takeoff_alt_m:.0f} m")

    def _runway_course(self, seq: int, t: Tick) -> float:
        """Take-off course: toward the next positioned item if it is away from here."""
        nxt = next_nav_index(self._items, seq + 1, dict(self._jump_counts))
        if nxt >= 0:
            n, e, _ = self._points[nxt]
            if not math.isnan(n) and math.hypot(n - t.pn, e - t.pe) > 50.0:
                return math.atan2(e - t.pe, n - t.pn)
        return t.state.yaw_rad

    def _course_out(self, seq: int, point: Point) -> float | None:
        """Course of the leg after waypoint ``seq`` (for turn anticipation), if a leg follows."""
        nxt = next_nav_index(self._items, seq + 1, dict(self._jump_counts))
        if nxt < 0 or self._items[nxt].command not in (MavCmd.NAV_WAYPOINT, MavCmd.NAV_LAND):
            return None
        n, e, _ = self._points[nxt]
        if math.isnan(n) or math.hypot(n - point[0], e - point[1]) < 1.0:
            return None
        return math.atan2(e - point[1], n - point[0])

    def _task_done(self) -> None:
        task = self._task
        t = self._tick_now()
        if isinstance(task, TakeoffTask):
            self._emit("Takeoff complete")
            self._prev_point = None
            if self.mode is FlightMode.TAKEOFF:
                self._hold_at((t.pn, t.pe, task.alt), "Takeoff done: loiter")
                return
            if self._after_takeoff_seq >= 0:
                seq, self._after_takeoff_seq = self._after_takeoff_seq, -1
                self._enter_item(seq)
                return
        elif isinstance(task, LandTask):
            self._emit("Landed")
            if self._in_mission and self.mode is FlightMode.MISSION:
                self._complete_item(self.current_seq)
            if self.armed:
                self.armed = False
                self._emit("Disarmed")
            self._in_mission = False
            self._set_mode(FlightMode.IDLE)
            self._task = IdleTask()
            return
        if self._in_mission and self.mode in (FlightMode.MISSION, FlightMode.RTL):
            self._complete_item(self.current_seq)
        else:
            self._hold_here("Hold")

    def _complete_item(self, seq: int) -> None:
        """Navigation item ``seq`` is done: record it, then move on."""
        item = self._items[seq]
        self._mark_reached(seq)
        if item.command == MavCmd.NAV_WAYPOINT:
            n, e, alt = self._points[seq]
            if not math.isnan(n):
                self._prev_point = (n, e, alt)
        else:
            self._prev_point = None
        if seq == self._first_flown:
            self._on_first_flown_reached()
        self._enter_item(seq + 1)

    def _on_established(self, task: LoiterTask) -> None:
        """The loiter of the current item reached its circle (called once per task)."""
        task.announced = True
        if not self._in_mission or not 0 <= self.current_seq < len(self._items):
            return
        seq = self.current_seq
        if seq == self._first_flown:
            self._on_first_flown_reached()
        cmd = self._items[seq].command
        if cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            # RTL is reached at home; later items (if any) follow, else it loiters on.
            self._complete_item(seq)
        elif cmd == MavCmd.NAV_LOITER_UNLIM:
            # Never ends; when nothing but DO items follow, the mission is complete.
            if next_nav_index(self._items, seq + 1, dict(self._jump_counts)) < 0:
                self._complete_item(seq)
            else:
                self._mark_reached(seq)

    def _on_first_flown_reached(self) -> None:
        if not self._has_capture_items and not self._default_capture_done:
            self._default_capture_done = True
            self._default_capture_pending = True

    def _finish_mission(self) -> None:
        """No navigation item left: loiter where the mission ended (RTL and loiters go on)."""
        self._mission_done()
        task = self._task
        if isinstance(task, LoiterTask) and not task.done:
            return
        if isinstance(task, LoiterTask) and task.done and self.mode is not FlightMode.RTL:
            task.done = False
            task.kind = LoiterKind.UNLIMITED
            self._set_mode(FlightMode.LOITER)
            return
        if isinstance(task, (LandTask, IdleTask)):
            return
        last = self._prev_point
        t = self._tick_now()
        if last is None:
            last = (t.pn, t.pe, t.alt)
        self._hold_at(last, "Mission finished: loiter")

    def _mission_done(self) -> None:
        if self.mission_completed:
            return
        self.mission_completed = True
        self._emit("Mission finished")
        if not self._has_capture_items and self.capturing:
            self._set_capture(False)
        self._default_capture_pending = False

    # ---------------------------------------------------------------------- mode helpers
    def _set_mode(self, mode: FlightMode) -> None:
        if mode is not self.mode:
            self.mode = mode
            self._emit(f"Mode: {mode.name}")

    def _set_capture(self, on: bool) -> None:
        if on != self.capturing:
            self.capturing = on
            self._emit("Capture started" if on else "Capture stopped")

    def _hold_at(self, point: Point, text: str) -> None:
        t = self._tick_now()
        self._task = LoiterTask(t, point, t.p.loiter_radius_m, 1)
        self._set_mode(FlightMode.LOITER)
        self._emit(text)

    def _hold_here(self, text: str) -> None:
        t = self._tick_now()
        self._hold_at((t.pn, t.pe, t.alt), text)

    def _start_rtl(self, t: Tick) -> None:
        alt = max(self.home.alt_amsl_m + t.p.rtl_alt_m, t.alt)
        self._task = LoiterTask(t, (0.0, 0.0, alt), t.p.loiter_radius_m, 1)
        self._set_mode(FlightMode.RTL)
        self._emit("Returning home")

    def _land_ahead(self, t: Tick) -> LandTask:
        """Glide straight ahead to a touchdown point on the FW_LND_ANG slope."""
        agl = max(0.0, t.alt - self.home.alt_amsl_m)
        dist = max(50.0, agl / math.tan(t.p.land_angle_rad))
        c = t.course
        td = (t.pn + dist * math.cos(c), t.pe + dist * math.sin(c), self.home.alt_amsl_m)
        return LandTask((t.pn, t.pe, t.alt), td)

    @property
    def on_ground(self) -> bool:
        """True before the first update or while the wheels touch."""
        return self._state is None or self._state.on_ground

    @property
    def task(self) -> Task:
        """The running task (for tests and telemetry)."""
        return self._task

    # ---------------------------------------------------------------------------- commands
    def arm(self) -> tuple[bool, str]:
        """Arm on the ground; in MISSION mode this starts the mission (as PX4)."""
        if self.armed:
            return True, "already armed"
        if not self.on_ground:
            return False, "not on the ground"
        if self.mode is FlightMode.MISSION and self._last_nav_seq < 0:
            return False, "no mission"
        if self.mode is FlightMode.MISSION and (far := self._too_far_to_fly()):
            return False, far
        self.armed = True
        self._emit("Armed")
        if self.mode is FlightMode.MISSION:
            self._begin_mission()
        elif self.mode is FlightMode.TAKEOFF:
            self._begin_takeoff(_NAN)
        return True, ""

    def disarm(self) -> tuple[bool, str]:
        """Disarm; refused in the air."""
        if not self.armed:
            return True, "already disarmed"
        if not self.on_ground:
            return False, "in the air"
        self.armed = False
        self._in_mission = False
        self._task = IdleTask()
        self._emit("Disarmed")
        return True, ""

    def set_mode(self, mode: FlightMode) -> tuple[bool, str]:
        """Switch flight mode (as a DO_SET_MODE from a ground station)."""
        if mode is FlightMode.MISSION:
            return self.start_mission()
        if mode is FlightMode.IDLE:
            if not self.on_ground:
                return False, "in the air"
            self._set_mode(FlightMode.IDLE)
            self._in_mission = False
            self._task = IdleTask()
            return True, ""
        if mode is FlightMode.TAKEOFF:
            return self.takeoff(_NAN)
        if mode is FlightMode.RTL:
            return self.return_to_launch()
        if self.on_ground:
            return False, "on the ground"
        if mode is FlightMode.LOITER:
            self._in_mission = False
            self._hold_here("Hold")
            return True, ""
        # LAND
        self._in_mission = False
        self._task = self._land_ahead(self._tick_now())
        self._set_mode(FlightMode.LAND)
        self._emit("Landing")
        return True, ""

    def start_mission(self) -> tuple[bool, str]:
        """Fly the mission from the current item (from the start when it was completed)."""
        if self._last_nav_seq < 0:
            return False, "no mission"
        if self.on_ground and (far := self._too_far_to_fly()):
            return False, far
        if self.mission_completed or not (0 <= self.current_seq < len(self._items)):
            self.current_seq = 0
            self._jump_counts = {}
            self.mission_completed = False
        self._set_mode(FlightMode.MISSION)
        if self.on_ground:
            if self.armed:
                self._begin_mission()
            return True, ""
        self._enter_item(self.current_seq)
        return True, ""

    def _too_far_to_fly(self) -> str:
        """Why the mission cannot start from the ground here ('' when it can).

        A plan uploaded for another place (a common slip: the vehicle still at its default
        home) would otherwise send the aircraft on a flight of hours toward it.
        """
        for point in self._points:
            if math.isfinite(point[0]):
                distance_m = math.hypot(point[0], point[1])
                if distance_m > MAX_FIRST_WAYPOINT_DISTANCE_M:
                    return (
                        f"first waypoint is {distance_m / 1000:.0f} km from home (limit "
                        f"{MAX_FIRST_WAYPOINT_DISTANCE_M / 1000:.0f} km): move home (--home, "
                        "--plan) or plan near the vehicle"
                    )
                break
        return ""

    def _begin_mission(self) -> None:
        if self._state is None:  # a command before the first update: start at the first one
            self._deferred = self._begin_mission
            return
        self._prev_point = None
        self._emit("Mission started")
        self._enter_item(max(0, self.current_seq))

    def set_current(self, seq: int) -> tuple[bool, str]:
        """Continue the mission at item ``seq`` (MISSION_SET_CURRENT)."""
        if not 0 <= seq < len(self._items):
            return False, f"item {seq} is not in the mission (0..{len(self._items) - 1})"
        self.current_seq = seq
        self.mission_completed = False
        self._prev_point = None
        if self.mode is FlightMode.MISSION and self._in_mission and not self.on_ground:
            self._enter_item(seq)
        return True, ""

    def takeoff(self, alt_m: float) -> tuple[bool, str]:
        """Take off to ``alt_m`` above home (NaN: MIS_TAKEOFF_ALT), then loiter."""
        if not self.on_ground:
            return False, "already in the air"
        self._set_mode(FlightMode.TAKEOFF)
        if self.armed:
            self._begin_takeoff(alt_m)
        return True, ""

    def _begin_takeoff(self, alt_m: float) -> None:
        if self._state is None:
            self._deferred = lambda: self._begin_takeoff(alt_m)
            return
        t = self._tick_now()
        rel = alt_m if math.isfinite(alt_m) and alt_m > 0 else t.p.takeoff_alt_m
        self._in_mission = False
        self._task = TakeoffTask(t, self.home.alt_amsl_m + rel, t.state.yaw_rad)
        self._emit(f"Takeoff to {rel:.0f} m")

    def return_to_launch(self) -> tuple[bool, str]:
        """Return home at RTL_RETURN_ALT (or higher) and loiter there."""
        if self.on_ground:
            return False, "on the ground"
        self._in_mission = False
        self._start_rtl(self._tick_now())
        return True, ""

    def reposition(self, lat_deg: float, lon_deg: float, alt_amsl_m: float) -> tuple[bool, str]:
        """Fly to a point and loiter there (NaN altitude: keep the current one)."""
        if self.on_ground:
            return False, "on the ground"
        if not (-90.0 <= lat_deg <= 90.0 and -180.0 <= lon_deg <= 180.0):
            return False, f"position out of range ({lat_deg}, {lon_deg})"
        t = self._tick_now()
        alt = alt_amsl_m if math.isfinite(alt_amsl_m) else t.alt
        n, e, _ = geodetic2ned(
            lat_deg, lon_deg, alt, self.home.lat_deg, self.home.lon_deg, self.home.alt_amsl_m
        )
        self._in_mission = False
        self._hold_at((n, e, alt), "Reposition")
        return True, ""

    def change_speed(self, speed_m_s: float) -> tuple[bool, str]:
        """New airspeed target (clamped to FW_AIRSPD_MIN..MAX); <= 0 restores the default."""
        if not math.isfinite(speed_m_s):
            return False, f"speed must be a number ({speed_m_s})"
        self._speed_override = speed_m_s if speed_m_s > 0 else None
        self._ground_speed_mode = False
        return True, ""

    def start_capture(self) -> tuple[bool, str]:
        """Open the capture window now."""
        self._set_capture(True)
        return True, ""

    def stop_capture(self) -> tuple[bool, str]:
        """Close the capture window now."""
        self._set_capture(False)
        return True, ""

    def air_start(self, state: VehicleState) -> None:
        """Begin in the air at the first flown item, armed, in MISSION mode, take-off done."""
        self._state = state
        first = self._first_flown
        if first < 0:
            msg = f"{self.mission.source}: mission: no waypoint or loiter to start in the air at"
            raise PlanError(msg)
        self.armed = True
        self._set_mode(FlightMode.MISSION)
        self._in_mission = True
        for seq in range(first):
            item = self._items[seq]
            if item.is_nav:
                self._mark_reached(seq)  # the take-off counts as flown
            elif item.command != MavCmd.DO_JUMP:
                self._run_do_item(seq)
        self._emit("Air start")
        if self._items[first].command == MavCmd.NAV_WAYPOINT:
            self.current_seq = first
            self._complete_item(first)
        else:
            self._enter_item(first)
