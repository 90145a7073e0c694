"""The autopilot facade: the one object the runner and the MAVLink endpoint talk to.

Guidance (the :class:`~air_sitl.autopilot.executor.MissionExecutor`) runs at 50 Hz, like a
PX4 position controller, and the attitude/energy controller at every physics step; everything
runs on the simulation thread. Commands return ``(accepted, reason)`` for COMMAND_ACK.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Protocol

from air_sitl.autopilot.executor import MissionExecutor, air_start_item
from air_sitl.autopilot.params import GuidanceParams, ParamStore
from air_sitl.autopilot.target import ControlPhase, ControlTarget, control_target
from air_sitl.frames import ned2geodetic
from air_sitl.mission.geometry import (
    SurfaceFn,
    item_point,
    loiter_geometry,
    next_nav_index,
)
from air_sitl.mission.items import LOITER_COMMANDS, WAYPOINT_COMMANDS, MavCmd, Mission
from air_sitl.state import (
    ActuatorCommand,
    AutopilotStatus,
    FlightMode,
    GeoPoint,
    VehicleState,
    autopilot_status,
)

GUIDANCE_PERIOD_NS = 20_000_000  # 50 Hz


class AttitudeController(Protocol):
    """What the autopilot needs of :class:`air_sitl.autopilot.control.Controller`."""

    def update(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        """Surface and throttle commands that pursue ``target``."""
        ...


class Autopilot:
    """Mission executor + guidance + controller behind one small API.

    ``auto_start`` (the ``fly`` command): arm and start the mission at the first update.
    ``air_start``: begin in the air at the first flown waypoint, armed, in MISSION mode, take-off
    done; place the flight model with :func:`air_start_pose`. Missions come validated from their
    edge (a plan file, a MAVLink upload) and are flown as they are. ``surface`` (``--dem``):
    the terrain model that terrain-relative items are flown above.
    """

    def __init__(
        self,
        mission: Mission,
        home: GeoPoint,
        params: ParamStore,
        controller: AttitudeController,
        *,
        air_start: bool = False,
        auto_start: bool = True,
        surface: SurfaceFn | None = None,
    ) -> None:
        self._exec = MissionExecutor(mission, home, params, surface=surface)
        self._controller = controller
        self._air_start_pending = air_start
        self._auto_start_pending = auto_start and not air_start
        if air_start:
            air_start_item(mission)
        self._next_nav_ns = -1
        # FW_P_LIM_MAX/MIN in radians, read again when the parameters change.
        self._pitch_limits_version = -1
        self._pitch_max_rad = self._pitch_min_rad = 0.0
        self._target = ControlTarget(phase=ControlPhase.IDLE)
        self._status = AutopilotStatus(
            mode=FlightMode.IDLE, armed=False, current_seq=-1, capturing=False,
            mission_completed=False,
        )  # fmt: skip

    # ------------------------------------------------------------------------- the loop
    def update(self, state: VehicleState) -> tuple[ActuatorCommand, AutopilotStatus]:
        """One physics step: guidance when due (or after a command), control always."""
        if state.sim_time_ns >= self._next_nav_ns:
            self._guidance(state)
        status = self._status
        queue = self._exec.reached_queue
        if queue:
            # Each reached item shows in exactly one status, even when several came at once;
            # the mission shows completed only once all of them have (a runner stops there).
            seq = queue.popleft()
            status = dataclasses.replace(
                status, reached_seq=seq, mission_completed=status.mission_completed and not queue
            )
        return self._controller.update(state, self._target), status

    def _guidance(self, state: VehicleState) -> None:
        ex = self._exec
        if self._air_start_pending:
            self._air_start_pending = False
            ex.air_start(state)
        if self._auto_start_pending:
            self._auto_start_pending = False
            ex.update(state)  # let it see the state first
            if state.on_ground:
                ex.set_mode(FlightMode.MISSION)
                ex.arm()
        nav = ex.update(state)
        params = ex.params
        if params.version != self._pitch_limits_version:
            self._pitch_limits_version = params.version
            self._pitch_max_rad = math.radians(params.in_range("FW_P_LIM_MAX"))
            self._pitch_min_rad = math.radians(params.in_range("FW_P_LIM_MIN"))
        t = nav.target
        self._target = control_target(  # positional, in ControlTarget's field order (50 Hz)
            t.phase,
            t.roll_rad,
            t.altitude_amsl_m,
            t.airspeed_m_s,
            t.heading_rad,
            t.climb_rate_limit_m_s,
            t.ground_amsl_m,
            self._pitch_max_rad,
            self._pitch_min_rad,
        )
        self._status = autopilot_status(  # positional, in AutopilotStatus's field order
            ex.mode,
            ex.armed,
            ex.current_seq,
            ex.capturing,
            ex.mission_completed,
            -1,
            nav.cross_track_m,
            nav.alt_error_m,
            nav.settled,
        )
        self._next_nav_ns = state.sim_time_ns + GUIDANCE_PERIOD_NS

    def _after_command(self) -> None:
        """Run guidance at the next step so a command takes effect at once."""
        self._next_nav_ns = -1

    # ------------------------------------------------------------------------ read-outs
    @property
    def mode(self) -> FlightMode:
        """Current flight mode."""
        return self._exec.mode

    @property
    def armed(self) -> bool:
        """Motor armed."""
        return self._exec.armed

    @property
    def home(self) -> GeoPoint:
        """Home: origin of the NED frame, RTL destination."""
        return self._exec.home

    @property
    def mission(self) -> Mission:
        """The mission being flown."""
        return self._exec.mission

    @property
    def params(self) -> ParamStore:
        """The parameter store (served over MAVLink)."""
        return self._exec.params

    @property
    def current_seq(self) -> int:
        """Index of the active mission item (MISSION_CURRENT), -1 with no mission."""
        return self._exec.current_seq

    @property
    def mission_completed(self) -> bool:
        """The last navigation item is done."""
        return self._exec.mission_completed

    @property
    def capturing(self) -> bool:
        """Inside the capture window."""
        return self._exec.capturing

    @property
    def status(self) -> AutopilotStatus:
        """Status after the last guidance update."""
        return self._status

    @property
    def last_target(self) -> ControlTarget:
        """What guidance asked of the controller at the last update."""
        return self._target

    @property
    def executor(self) -> MissionExecutor:
        """The mission state machine (tests, diagnostics)."""
        return self._exec

    def pop_events(self) -> list[str]:
        """STATUSTEXT-style messages (mode changes, take-off, capture, mission end)."""
        return self._exec.pop_events()

    def pop_reached(self) -> list[int]:
        """Mission items reached since the last call (MISSION_ITEM_REACHED)."""
        return self._exec.pop_reached()

    # ------------------------------------------------------------------------- commands
    def arm(self) -> tuple[bool, str]:
        """Arm (on the ground only); in MISSION mode the mission starts."""
        self._auto_start_pending = False
        self._after_command()
        return self._exec.arm()

    def disarm(self) -> tuple[bool, str]:
        """Disarm (on the ground only)."""
        self._auto_start_pending = False
        self._after_command()
        return self._exec.disarm()

    def crashed(self) -> None:
        """The vehicle crashed: disarm at once, in the air or not (see :meth:`disarm`)."""
        self._auto_start_pending = False
        self._exec.crashed()

    def set_mode(self, mode: FlightMode) -> tuple[bool, str]:
        """Change flight mode."""
        self._after_command()
        return self._exec.set_mode(mode)

    def start_mission(self) -> tuple[bool, str]:
        """Fly the mission (MISSION_START)."""
        self._after_command()
        return self._exec.start_mission()

    def set_mission(self, mission: Mission, current_seq: int | None = None) -> None:
        """Replace the mission (validated at its edge: a plan file, a MAVLink upload).
        ``current_seq``: see :meth:`MissionSequencer.set_mission` (-1 keeps the current index,
        as PX4)."""
        self._after_command()
        self._exec.set_mission(mission, current_seq)

    def set_current(self, seq: int) -> tuple[bool, str]:
        """Continue at item ``seq``."""
        self._after_command()
        return self._exec.set_current(seq)

    def takeoff(self, alt_m: float = math.nan) -> tuple[bool, str]:
        """Take off to ``alt_m`` above home, then loiter."""
        self._after_command()
        return self._exec.takeoff(alt_m)

    def return_to_launch(self) -> tuple[bool, str]:
        """Return home and loiter."""
        self._after_command()
        return self._exec.return_to_launch()

    def reposition(self, lat_deg: float, lon_deg: float, alt_amsl_m: float) -> tuple[bool, str]:
        """Fly to a point and loiter (NaN altitude keeps the current one)."""
        self._after_command()
        return self._exec.reposition(lat_deg, lon_deg, alt_amsl_m)

    def change_speed(self, speed_m_s: float) -> tuple[bool, str]:
        """Airspeed target; <= 0 returns to the mission/trim speed."""
        self._after_command()
        return self._exec.change_speed(speed_m_s)

    def start_capture(self) -> tuple[bool, str]:
        """Open the capture window."""
        self._after_command()
        return self._exec.start_capture()

    def stop_capture(self) -> tuple[bool, str]:
        """Close the capture window."""
        self._after_command()
        return self._exec.stop_capture()


def air_start_pose(
    mission: Mission,
    home: GeoPoint,
    params: ParamStore | None = None,
    surface: SurfaceFn | None = None,
) -> tuple[float, float, float, float, float]:
    """Where an air start begins: (lat_deg, lon_deg, alt_amsl_m, heading_rad, airspeed_m_s).

    At the first waypoint after take-off, at its altitude, heading along the first leg (toward
    the next positioned item; tangent to a loiter circle that passes through the point), at the
    mission speed (DO_CHANGE_SPEED before that point, else the plan's cruise speed).
    """
    params = params or ParamStore()
    items = mission.items
    first = air_start_item(mission)
    speed = mission.cruise_speed_m_s
    if not (math.isfinite(speed) and speed > 0.0):
        speed = params.in_range("FW_AIRSPD_TRIM")
    for item in items[:first]:
        if (
            item.command == MavCmd.DO_CHANGE_SPEED
            and item.param1 in (0.0, 1.0)
            and item.param2 > 0.0
        ):
            speed = item.param2
    speed = GuidanceParams.from_store(params).clamp_speed(speed)
    n, e, alt = item_point(items[first], home, surface)
    if math.isnan(n):
        n, e = 0.0, 0.0
    default_radius = params.in_range("NAV_LOITER_RAD")
    if items[first].command not in WAYPOINT_COMMANDS:
        # Start on the loiter circle, on the side facing home, flying along it.
        radius, direction = loiter_geometry(items[first], default_radius)
        bearing = math.atan2(-e, -n) if math.hypot(n, e) > 1.0 else 0.0
        cn, ce = n, e
        n, e = cn + radius * math.cos(bearing), ce + radius * math.sin(bearing)
        heading = bearing + direction * 0.5 * math.pi
    else:
        heading = math.atan2(e, n) if math.hypot(n, e) > 1.0 else 0.0
        nxt = next_nav_index(items, first + 1, {})
        if nxt >= 0:
            nn, ne, _ = item_point(items[nxt], home)
            if not math.isnan(nn) and math.hypot(nn - n, ne - e) > 1.0:
                heading = math.atan2(ne - e, nn - n)
                if items[nxt].command in LOITER_COMMANDS:
                    radius, direction = loiter_geometry(items[nxt], default_radius)
                    dist = math.hypot(nn - n, ne - e)
                    if dist < 1.5 * radius:
                        # The point is near the circle: fly along its tangent.
                        heading = math.atan2(e - ne, n - nn) + direction * 0.5 * math.pi
    lat, lon, _ = ned2geodetic(n, e, 0.0, home.lat_deg, home.lon_deg, home.alt_amsl_m)
    heading = (heading + math.pi) % (2.0 * math.pi) - math.pi
    return lat, lon, alt, heading, speed
