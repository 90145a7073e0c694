"""The mission state machine: modes, mission items, capture window, and what to fly now.

:class:`MissionSequencer` turns a :class:`~air_sitl.mission.items.Mission` and the vehicle state
into a :class:`~air_sitl.autopilot.target.ControlTarget`. It runs one navigation *task* at a
time (:mod:`air_sitl.autopilot.tasks`: take-off, leg, loiter, landing, idle on the ground).
Sequencing follows PX4: DO_* items run when reached (:mod:`air_sitl.autopilot.do_items`), the
aircraft loiters at the last waypoint when a mission ends, RTL climbs (never descends) to
RTL_RETURN_ALT and loiters at home.

The mission comes validated from its edge (:func:`~air_sitl.mission.plan_file.load_mission`,
a MAVLink upload through :mod:`air_sitl.mavlink.mission_protocol`); nothing here checks it again.

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

from air_sitl.autopilot.do_items import DoItems
from air_sitl.autopilot.params import GuidanceParams, ParamStore
from air_sitl.autopilot.tasks import (
    IdleTask,
    LandTask,
    LegTask,
    LoiterKind,
    LoiterTask,
    NavOutput,
    TakeoffTask,
    Task,
    Tick,
    WaitTask,
)
from air_sitl.autopilot.terrain import TerrainFollower, ground_amsl
from air_sitl.mission.geometry import (
    MAX_DO_STEPS,
    Point,
    SurfaceFn,
    first_flown_item,
    item_point,
    loiter_geometry,
    next_nav_index,
)
from air_sitl.mission.items import (
    CAPTURE_COMMANDS,
    LOITER_COMMANDS,
    TERRAIN_FRAMES,
    WAYPOINT_COMMANDS,
    MavCmd,
    Mission,
)
from air_sitl.mission.validate import item_warnings
from air_sitl.state import FlightMode, GeoPoint, VehicleState

MAX_PENDING = 1000  # events and reached items kept for a reader that does not come


class MissionSequencer:
    """Modes, mission sequencing and the capture window; one :class:`Task` at a time.

    Everything runs on the simulation thread. The commands that change modes live in the
    subclass :class:`~air_sitl.autopilot.executor.MissionExecutor`. ``surface`` (``--dem``):
    the terrain model terrain-relative items are flown above (:mod:`air_sitl.autopilot.terrain`).
    """

    def __init__(
        self,
        mission: Mission,
        home: GeoPoint,
        params: ParamStore,
        *,
        surface: SurfaceFn | None = None,
    ) -> None:
        self.home = home
        self._surface = surface
        self._terrain = TerrainFollower(surface) if surface is not None else None
        self.params = params
        self._params_version = -1
        self._guidance_params = GuidanceParams.from_store(params)
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
        self._do = DoItems(self._emit, self._set_capture)
        self._after_takeoff_seq = -1  # mission item to enter after an implicit take-off
        self._in_mission = False  # flying mission items (as opposed to waiting on the ground)
        self._deferred: Callable[[], None] | None = None  # a command that needs a state first
        self._set_mission_fields(mission)

    # ----------------------------------------------------------------------------- mission
    def _set_mission_fields(self, mission: Mission) -> None:
        self.mission = mission
        self._items = mission.items
        self._points = [item_point(item, self.home, self._surface) for item in mission.items]
        self._do.new_mission()
        self._prev_point: Point | None = None
        self._has_capture_items = any(item.command in CAPTURE_COMMANDS for item in mission.items)
        # PX4's mission landing: RTL flies the landing sequence from its DO_LAND_START.
        self._land_start = next(
            (i for i, item in enumerate(mission.items) if item.command == MavCmd.DO_LAND_START),
            -1,
        )
        self._first_flown = first_flown_item(mission)
        self._default_capture_pending = False
        self._default_capture_done = False
        self._last_nav_seq = max(
            (i for i, item in enumerate(mission.items) if item.is_nav), default=-1
        )
        self.current_seq = 0 if mission.items else -1
        self.mission_completed = False
        for warning in item_warnings(mission.items):
            self._emit(f"Mission: {warning}")

    def set_mission(self, mission: Mission, current_seq: int | None = None) -> None:
        """Replace the mission (PX4-like: allowed on the ground and in flight).

        ``current_seq`` None: the new mission starts at its first item (a plan loaded by the
        fly command). Otherwise, as PX4 after an upload: the item flagged current by the ground
        station, or (-1, none flagged) the current index kept, clamped to the new list; in
        MISSION mode in the air that item is flown next, nothing before it is re-reported.
        """
        keep = self.current_seq
        self._set_mission_fields(mission)
        self._do.set_speed(None)  # the new plan's speeds apply
        self._emit(f"Mission replaced: {len(mission.items)} items")
        seq = 0
        if current_seq is not None and mission.items:
            seq = current_seq if current_seq >= 0 else keep
            seq = min(max(seq, 0), len(mission.items) - 1)
            self.current_seq = seq
        if self.mode is FlightMode.MISSION and self._in_mission and self._state is not None:
            if mission.items:
                self._enter_item(seq)
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
    def guidance_params(self) -> GuidanceParams:
        """Current parameters, re-read when the store changed."""
        if self.params.version != self._params_version:
            self._guidance_params = GuidanceParams.from_store(self.params)
            self._params_version = self.params.version
        return self._guidance_params

    def _speed(self, p: GuidanceParams, course_rad: float = 0.0) -> float:
        asked = self._do.airspeed(p, course_rad)
        if asked is not None:
            return asked
        plan = self.mission.cruise_speed_m_s
        if self.mode is FlightMode.MISSION and math.isfinite(plan) and plan > 0.0:
            return p.clamp_speed(plan)
        return p.clamp_speed(p.trim_m_s)

    def update(self, state: VehicleState) -> NavOutput:
        """Advance the state machine and return guidance for ``state``."""
        self._state = state
        p = self.guidance_params
        if self._deferred is not None:
            deferred, self._deferred = self._deferred, None
            deferred()
        self._do.update(state)
        tick = self._tick = self._tick_now(p)
        out = self._task.update(tick)
        # Tasks may finish several in a row (a waypoint, then DO items): bounded by the items.
        for _ in range(len(self._items) + 4):
            if not self._task.done:
                break
            self._task_done()
            tick.speed = self._speed(p, tick.course)
            out = self._task.update(tick)
        task = self._task
        if self._terrain is not None and isinstance(task, (LegTask, LoiterTask)):
            out = self._follow_terrain(out, tick)
        if isinstance(task, LoiterTask) and task.established and not task.announced:
            self._on_established(task)
        if self._default_capture_pending and (
            abs(state.alt_amsl_m - self._points[self._first_flown][2]) <= p.alt_acc_m
        ):
            self._default_capture_pending = False
            self._set_capture(True)
        return out

    def _follow_terrain(self, out: NavOutput, tick: Tick) -> NavOutput:
        """A leg or loiter toward a terrain-relative mission item keeps its height above the
        surface under the aircraft, not the item's altitude at the item."""
        seq = self.current_seq
        if not (self._in_mission and 0 <= seq < len(self._items)):
            return out
        item = self._items[seq]
        if item.frame not in TERRAIN_FRAMES or self.mode is not FlightMode.MISSION:
            return out
        assert self._terrain is not None
        return self._terrain.follow(out, tick, item.alt_m)

    def _tick_now(self, p: GuidanceParams | None = None) -> Tick:
        """A tick for the last state (commands create tasks between updates); ``p``: the
        parameters now, when the caller has them (guidance, at 50 Hz)."""
        assert self._state is not None
        if p is None:
            p = self.guidance_params
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
            if steps > MAX_DO_STEPS:
                self._emit("Mission: DO_JUMP loop without navigation items")
                break
            self.current_seq = seq
            seq = self._do.run(items, seq, capturing=self.capturing)
        self._finish_mission()

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
        elif cmd in WAYPOINT_COMMANDS:
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
        elif cmd in LOITER_COMMANDS:
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
        elif cmd == MavCmd.NAV_DELAY:
            if t.state.on_ground:
                self._task = WaitTask(t, item.param1)
            else:
                self._task = LoiterTask(
                    t, here, p.loiter_radius_m, 1, LoiterKind.DELAY, item.param1
                )
            self._emit(f"Delay {item.param1:g} s")
        elif cmd == MavCmd.NAV_RETURN_TO_LAUNCH:
            if t.state.on_ground:
                self._complete_item(seq)
                return
            if self._landing_sequence_for(seq):
                self._mark_reached(seq)
            self._start_rtl(t)
        elif cmd == MavCmd.NAV_LAND:
            if t.state.on_ground:
                self._complete_item(seq)
                return
            if math.isnan(self._points[seq][0]):
                self._task = LandTask.ahead(t, self.ground_below(t))
            else:
                ground = ground_amsl(self._surface, self.home, item.lat_deg, item.lon_deg)
                prev = self._prev_point if self._prev_point is not None else here
                td = (n, e, max(ground, min(alt, ground + 1.0)))
                self._task = LandTask(prev, td, ground)
            self._emit("Landing")

    def ground_below(self, t: Tick) -> float:
        """The ground under the aircraft (where it flies on: the onboard estimate)."""
        return ground_amsl(self._surface, self.home, t.state.lat_deg, t.state.lon_deg)

    def _implicit_takeoff(self, seq: int) -> None:
        """A mission started on the ground without a take-off item climbs out first."""
        t = self._tick_now()
        self._after_takeoff_seq = seq
        alt = self.home.alt_amsl_m + t.p.takeoff_alt_m
        self._task = TakeoffTask(t, alt, self._runway_course(seq - 1, t))
        self._emit(f"Takeoff to {t.p.takeoff_alt_m:.0f} m")

    def _runway_course(self, seq: int, t: Tick) -> float:
        """Take-off course: toward the next positioned item if it is away from here."""
        nxt = next_nav_index(self._items, seq + 1, dict(self._do.jump_counts))
        if nxt >= 0:
            n, e, _ = self._points[nxt]
            if not math.isnan(n) and math.hypot(n - t.pn, e - t.pe) > 50.0:
                return math.atan2(e - t.pe, n - t.pn)
        return t.state.yaw_rad

    def _course_out(self, seq: int, point: Point) -> float | None:
        """Course of the leg after waypoint ``seq`` (for turn anticipation), if a leg follows."""
        nxt = next_nav_index(self._items, seq + 1, dict(self._do.jump_counts))
        if nxt < 0 or self._items[nxt].command not in (*WAYPOINT_COMMANDS, MavCmd.NAV_LAND):
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
            if self._in_mission and self.mode in (FlightMode.MISSION, FlightMode.RTL):
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
        if item.command in WAYPOINT_COMMANDS:
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
            if next_nav_index(self._items, seq + 1, dict(self._do.jump_counts)) < 0:
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

    def _landing_sequence_for(self, seq: int) -> bool:
        """RTL from mission item ``seq`` (-1: a command) flies the mission landing."""
        return self._land_start >= 0 and not (self._in_mission and seq > self._land_start)

    def _start_rtl(self, t: Tick) -> None:
        seq = self.current_seq if self._in_mission else -1
        if self._landing_sequence_for(seq):
            # PX4 (fixed wing): return along the mission landing pattern, from DO_LAND_START.
            self._set_mode(FlightMode.RTL)
            self._emit(f"Returning: mission landing from item {self._land_start}")
            self._in_mission = True
            self._prev_point = None
            self._enter_item(self._land_start)
            return
        alt = max(self.home.alt_amsl_m + t.p.rtl_alt_m, t.alt)
        self._task = LoiterTask(t, (0.0, 0.0, alt), t.p.loiter_radius_m, 1)
        self._set_mode(FlightMode.RTL)
        self._emit("Returning home")

    @property
    def on_ground(self) -> bool:
        """True before the first update or while the wheels touch."""
        return self._state is None or self._state.on_ground

    @property
    def task(self) -> Task:
        """The running task (for tests and telemetry)."""
        return self._task
