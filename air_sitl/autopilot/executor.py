"""The mission executor: the commands a ground station (or the fly command) gives the
mission state machine of :class:`~air_sitl.autopilot.sequencer.MissionSequencer`.

Arming, flight modes, take-off, RTL, reposition, speed, the capture window and air starts; each
command returns ``(accepted, reason)`` for COMMAND_ACK.
"""

from __future__ import annotations

import math

from air_sitl.autopilot.sequencer import MissionSequencer
from air_sitl.autopilot.tasks import IdleTask, LandTask, TakeoffTask
from air_sitl.errors import PlanError
from air_sitl.frames import geodetic2ned
from air_sitl.mission.geometry import first_flown_item
from air_sitl.mission.items import WAYPOINT_COMMANDS, MavCmd, Mission
from air_sitl.mission.validate import takeoff_order_problem
from air_sitl.state import FlightMode, VehicleState

# Mission start refused when its first positioned item is farther than this from home.
MAX_FIRST_WAYPOINT_DISTANCE_M = 100_000.0


def air_start_item(mission: Mission) -> int:
    """The item an air start begins at; PlanError when the mission has none."""
    first = first_flown_item(mission)
    if first < 0:
        msg = f"{mission.source}: mission: no waypoint or loiter to start in the air at"
        raise PlanError(msg)
    return first


class MissionExecutor(MissionSequencer):
    """Modes, arming, mission sequencing and the capture window, driven by commands.

    Everything runs on the simulation thread. Commands return ``(accepted, reason)``.
    """

    def arm(self) -> tuple[bool, str]:
        """Arm on the ground; in MISSION mode this starts the mission (as PX4)."""
        if self.armed:
            return True, "already armed"
        if not self.on_ground:
            return False, "not on the ground"
        if self.mode is FlightMode.MISSION and self._last_nav_seq < 0:
            return False, "no mission"
        if self.mode is FlightMode.MISSION and (order := takeoff_order_problem(self._items)):
            return False, order
        if self.mode is FlightMode.MISSION and (far := self._too_far_to_fly()):
            return False, far
        self.armed = True
        self._emit("Armed")
        if self.mode is FlightMode.MISSION:
            self._begin_mission()
        elif self.mode is FlightMode.TAKEOFF:
            self._begin_takeoff(math.nan)
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

    def crashed(self) -> None:
        """Motors off wherever the vehicle is: it met the ground outside a landing (a served
        vehicle after a crash; PX4's land detector would disarm it on the ground)."""
        self.armed = False
        self._in_mission = False
        self._task = IdleTask()

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
            return self.takeoff(math.nan)
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
        t = self._tick_now()
        self._task = LandTask.ahead(t, self.ground_below(t))
        self._set_mode(FlightMode.LAND)
        self._emit("Landing")
        return True, ""

    def start_mission(self) -> tuple[bool, str]:
        """Fly the mission from the current item (from the start when it was completed)."""
        if self._last_nav_seq < 0:
            return False, "no mission"
        if order := takeoff_order_problem(self._items):
            return False, order
        if self.on_ground and (far := self._too_far_to_fly()):
            return False, far
        if self.mission_completed or not (0 <= self.current_seq < len(self._items)):
            self.current_seq = 0
            self._do.jump_counts = {}
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
        self._do.set_speed(speed_m_s if speed_m_s > 0 else None)
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
        first = air_start_item(self.mission)
        self.armed = True
        self._set_mode(FlightMode.MISSION)
        self._in_mission = True
        for seq in range(first):
            item = self._items[seq]
            if item.is_nav:
                self._mark_reached(seq)  # the take-off counts as flown
            elif item.command != MavCmd.DO_JUMP:
                self._do.run(self._items, seq, capturing=self.capturing)
        self._emit("Air start")
        if self._items[first].command in WAYPOINT_COMMANDS:
            self.current_seq = first
            self._complete_item(first)
        else:
            self._enter_item(first)
