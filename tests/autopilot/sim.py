"""Test helpers: mission builders and a kinematic aircraft that flies ControlTargets.

The kinematic aircraft is the scripted fake of the test suite (the real JSBSim model flies in
``test_flight.py``): a coordinated-turn point mass whose bank, altitude and airspeed follow the
target with first-order lags. It tests guidance and sequencing, not control.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from air_sitl.autopilot.autopilot import air_start_pose
from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.params import ParamStore
from air_sitl.autopilot.target import ControlPhase, ControlTarget
from air_sitl.autopilot.tasks import NavOutput
from air_sitl.frames import euler2quat, geodetic2ned, ned2geodetic
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.state import FlightMode, GeoPoint, VehicleState

HOME = GeoPoint(lat_deg=54.68, lon_deg=25.28, alt_amsl_m=120.0)
G = 9.80665
DT_NS = 20_000_000  # the executor runs at 50 Hz


def wp(n: float, e: float, alt: float, cmd: int = MavCmd.NAV_WAYPOINT, **kw: float) -> MissionItem:
    """A positioned item at (north, east) metres from HOME, ``alt`` metres above home."""
    lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    return MissionItem(command=cmd, lat_deg=lat, lon_deg=lon, alt_m=alt, **kw)  # type: ignore[arg-type]


def do(cmd: int, **kw: float) -> MissionItem:
    """A DO_* item."""
    return MissionItem(command=cmd, frame=MavFrame.MISSION, **kw)  # type: ignore[arg-type]


def rtl() -> MissionItem:
    """NAV_RETURN_TO_LAUNCH."""
    return MissionItem(command=MavCmd.NAV_RETURN_TO_LAUNCH, frame=MavFrame.MISSION)


def mission(*items: MissionItem, speed: float = 15.0) -> Mission:
    """A mission of ``items`` with HOME as planned home."""
    return Mission(items=items, planned_home=HOME, cruise_speed_m_s=speed, source="test")


class KinematicPlane:
    """Coordinated-turn point mass in HOME's NED frame; flies ControlTargets."""

    def __init__(
        self,
        n: float = 0.0,
        e: float = 0.0,
        alt_rel: float = 0.0,
        course_rad: float = 0.0,
        airspeed: float = 0.0,
        wind_ne: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        self.n, self.e, self.alt = n, e, HOME.alt_amsl_m + alt_rel
        self.psi = course_rad
        self.v = airspeed
        self.phi = 0.0
        self.vz = 0.0
        self.wind = wind_ne
        self.t_ns = 0
        self.on_ground = alt_rel <= 0.0

    def state(self) -> VehicleState:
        """The current VehicleState."""
        vn = self.v * math.cos(self.psi) + (0.0 if self.on_ground else self.wind[0])
        ve = self.v * math.sin(self.psi) + (0.0 if self.on_ground else self.wind[1])
        lat = HOME.lat_deg + self.n / 111_320.0
        lon = HOME.lon_deg + self.e / (111_320.0 * math.cos(math.radians(HOME.lat_deg)))
        return VehicleState(
            sim_time_ns=self.t_ns,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=self.alt,
            alt_agl_m=self.alt - HOME.alt_amsl_m,
            pos_ned_m=(self.n, self.e, HOME.alt_amsl_m - self.alt),
            q_body_to_ned_wxyz=euler2quat(self.phi, 0.0, self.psi),
            roll_rad=self.phi,
            pitch_rad=0.0,
            yaw_rad=(self.psi + math.pi) % (2 * math.pi) - math.pi,
            vel_ned_m_s=(vn, ve, self.vz),
            rate_frd_rad_s=(0.0, 0.0, 0.0),
            specific_force_frd_m_s2=(0.0, 0.0, -G),
            airspeed_m_s=self.v,
            on_ground=self.on_ground,
        )

    def step(self, target: ControlTarget, dt_s: float = DT_NS / 1e9) -> VehicleState:
        """Advance ``dt_s`` following ``target``."""
        phase = target.phase
        ground = HOME.alt_amsl_m
        if phase is ControlPhase.IDLE:
            self.v = max(0.0, self.v - 3.0 * dt_s) if self.on_ground else self.v
        elif self.on_ground and phase is ControlPhase.GROUND_ROLL:
            self.v += 3.0 * dt_s
            self.psi = target.heading_rad
            if self.v >= 12.0:
                self.on_ground = False
                self.alt = ground + 0.5
        elif self.on_ground:  # rolling out after landing
            self.v = max(0.0, self.v - 2.0 * dt_s)
            self.phi = 0.0
        else:
            self.phi += (target.roll_rad - self.phi) * min(1.0, dt_s / 0.3)
            if phase is ControlPhase.CLIMB or phase is ControlPhase.GROUND_ROLL:
                climb = 3.0
            else:
                climb = max(
                    -target.climb_rate_limit_m_s,
                    min(target.climb_rate_limit_m_s, 0.3 * (target.altitude_amsl_m - self.alt)),
                )
                if phase is ControlPhase.LAND:
                    climb = max(min(climb, -0.5), -2.0)  # flare, then touch down
            self.vz = -climb
            self.alt += climb * dt_s
            self.v += (target.airspeed_m_s - self.v) * min(1.0, dt_s / 2.0)
            self.psi += G * math.tan(self.phi) / max(self.v, 5.0) * dt_s
            if self.alt <= ground:
                self.alt = ground
                self.on_ground = True
                self.vz = 0.0
        vn = self.v * math.cos(self.psi) + (0.0 if self.on_ground else self.wind[0])
        ve = self.v * math.sin(self.psi) + (0.0 if self.on_ground else self.wind[1])
        self.n += vn * dt_s
        self.e += ve * dt_s
        self.t_ns += round(dt_s * 1e9)
        return self.state()


def run(
    ex: MissionExecutor,
    plane: KinematicPlane,
    *,
    max_s: float = 2000.0,
    until: Callable[[MissionExecutor, VehicleState], bool] | None = None,
    each: Callable[[MissionExecutor, VehicleState, NavOutput], None] | None = None,
) -> VehicleState:
    """Fly the executor until ``until`` (default: mission completed) or ``max_s``."""
    state = plane.state()
    stop = until or (lambda x, _s: x.mission_completed)
    while state.sim_time_ns < max_s * 1e9:
        out = ex.update(state)
        if each is not None:
            each(ex, state, out)
        if stop(ex, state):
            return state
        state = plane.step(out.target)
    return state


def air_started(
    m: Mission, wind_ne: tuple[float, float] = (0.0, 0.0)
) -> tuple[MissionExecutor, KinematicPlane]:
    """An executor begun in the air at the mission's start point, and a plane placed there."""
    lat, lon, alt, heading, speed = air_start_pose(m, HOME)
    n, e, _ = geodetic2ned(lat, lon, alt, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    plane = KinematicPlane(n, e, alt - HOME.alt_amsl_m, heading, speed, wind_ne)
    ex = MissionExecutor(m, HOME, ParamStore())
    ex.air_start(plane.state())
    return ex, plane


def ground_started(m: Mission) -> tuple[MissionExecutor, KinematicPlane]:
    """An executor on the ground at home, armed in MISSION mode (flying from the next update),
    and a plane standing there."""
    ex = MissionExecutor(m, HOME, ParamStore())
    plane = KinematicPlane()
    ex.update(plane.state())
    ex.set_mode(FlightMode.MISSION)
    ex.arm()
    return ex, plane
