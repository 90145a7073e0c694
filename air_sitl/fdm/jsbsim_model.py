"""JSBSim flight model adapter: the only module that imports ``jsbsim``.

Loads our own ``airsitl_uav`` (package data under ``fdm/aircraft``) or any aircraft the jsbsim
wheel ships, steps it at the physics rate and turns its properties into :class:`VehicleState`.
JSBSim's feet, slugs and degrees stay inside this module.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import jsbsim
import numpy as np

from air_sitl.clock import NS_PER_S, PHYSICS_STEP_NS
from air_sitl.errors import AircraftError
from air_sitl.fdm import state_kernel
from air_sitl.fdm.base import InitialCondition, Terrain, Wind
from air_sitl.frames import WGS84_A_M, WGS84_E2
from air_sitl.state import ActuatorCommand, GeoPoint, VehicleState, vehicle_state

FT_M = 0.3048
M_FT = 1.0 / FT_M
DEFAULT_AIRCRAFT = "airsitl_uav"
OWN_AIRCRAFT_DIR = Path(__file__).resolve().parent / "aircraft"

# Properties read every step, in the order _build_state unpacks them.
_STATE_PROPERTIES = (
    "position/lat-geod-deg",
    "position/long-gc-deg",
    "position/geod-alt-ft",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "velocities/p-rad_sec",
    "velocities/q-rad_sec",
    "velocities/r-rad_sec",
    "accelerations/a-pilot-x-ft_sec2",
    "accelerations/a-pilot-y-ft_sec2",
    "accelerations/a-pilot-z-ft_sec2",
    "velocities/vtrue-fps",
    "gear/wow",
)


@contextlib.contextmanager
def _quiet_stdout() -> Iterator[None]:
    """Silence JSBSim's C++ prints (its trim writes "Sorry, ... not trimmable" to stdout)."""
    if sys.stdout is not None:
        sys.stdout.flush()
    try:
        saved = os.dup(1)
    except OSError:  # no stdout at all: nothing to silence
        yield
        return
    try:
        with open(os.devnull, "wb") as devnull:
            os.dup2(devnull.fileno(), 1)
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def _wheel_root() -> Path:
    return Path(jsbsim.get_default_root_dir())


def _aircraft_in(directory: Path) -> list[str]:
    if not directory.is_dir():
        return []
    return sorted(p.name for p in directory.iterdir() if (p / f"{p.name}.xml").is_file())


def available_aircraft() -> list[str]:
    """Names accepted by :class:`JSBSimModel`: ours first, then the jsbsim wheel's."""
    own = _aircraft_in(OWN_AIRCRAFT_DIR)
    wheel = [name for name in _aircraft_in(_wheel_root() / "aircraft") if name not in own]
    return own + wheel


def _wind_ned_fps(wind: Wind) -> tuple[float, float]:
    """North/east wind velocity (where the air moves TO) in ft/s, from speed and FROM-direction."""
    from_rad = math.radians(wind.from_deg)
    speed_fps = wind.speed_m_s * M_FT
    return (-speed_fps * math.cos(from_rad), -speed_fps * math.sin(from_rad))


class _LocalNed:
    """The origin of the local NED frame: its ECEF position and rotation, for ``_build_state``
    (which turns each geodetic position into NED from these, compiled: state_kernel)."""

    def __init__(self, origin: GeoPoint) -> None:
        lat = math.radians(origin.lat_deg)
        lon = math.radians(origin.lon_deg)
        self.x0, self.y0, self.z0 = self._ecef(lat, lon, origin.alt_amsl_m)
        sl, cl = math.sin(lat), math.cos(lat)
        so, co = math.sin(lon), math.cos(lon)
        self.m = (-sl * co, -sl * so, cl, -so, co, -cl * co, -cl * so, -sl)
        self.array = np.array([self.x0, self.y0, self.z0, *self.m])  # state_kernel's origin

    @staticmethod
    def _ecef(lat: float, lon: float, alt_m: float) -> tuple[float, float, float]:
        sin_lat = math.sin(lat)
        n = WGS84_A_M / math.sqrt(1.0 - WGS84_E2 * sin_lat * sin_lat)
        r = (n + alt_m) * math.cos(lat)
        return (r * math.cos(lon), r * math.sin(lon), (n * (1.0 - WGS84_E2) + alt_m) * sin_lat)


class JSBSimModel:
    """A JSBSim aircraft behind the :class:`~air_sitl.fdm.base.FlightModel` protocol.

    ``substeps`` JSBSim frames make one physics step (``step_ns``); the default of 1 is
    stable for airsitl_uav and the wheel's light aircraft. ``seed`` seeds JSBSim's
    turbulence (``Wind.turbulence`` > 0), so gusty flights repeat exactly. After
    :meth:`reset` of an airborne start, :attr:`trim_command` holds the trimmed controls.
    ``terrain`` (``--dem``): JSBSim's ground follows it under the aircraft (set after every
    step for the next one) and states carry the ground and surface heights beneath.
    """

    def __init__(
        self,
        aircraft: str = DEFAULT_AIRCRAFT,
        *,
        step_ns: int = PHYSICS_STEP_NS,
        substeps: int = 1,
        seed: int = 0,
        terrain: Terrain | None = None,
    ) -> None:
        if step_ns <= 0 or substeps < 1:
            msg = f"JSBSimModel: step_ns {step_ns} and substeps {substeps} must be positive"
            raise AircraftError(msg)
        names = available_aircraft()
        if aircraft not in names:
            shown = ", ".join(n for n in (DEFAULT_AIRCRAFT, "c172p", "J3Cub", "pa28") if n in names)
            msg = (
                f"unknown aircraft {aircraft!r}: expected {shown} or another of the "
                f"{len(names)} JSBSim models installed"
            )
            raise AircraftError(msg)
        self.aircraft = aircraft
        self.step_ns = step_ns
        self._substeps = substeps
        self._seed = seed
        self._terrain = terrain
        self._set_terrain_ft: Any = None
        self._dt_s = step_ns / NS_PER_S / substeps
        self._own = (OWN_AIRCRAFT_DIR / aircraft / f"{aircraft}.xml").is_file()
        self.trim_command = ActuatorCommand()
        self._time_ns = 0
        self._ground = GeoPoint(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0)
        self._ned = _LocalNed(self._ground)
        self._fdm: Any = None
        self._getters: tuple[Any, ...] = ()
        self._run: Any = None
        self._set_elevator: Any = None
        self._set_aileron: Any = None
        self._set_rudder: Any = None
        self._set_steer: Any = None
        self._set_throttle: Any = None
        self._set_brake_left: Any = None
        self._set_brake_right: Any = None
        self._setters: tuple[Any, ...] = ()  # the seven above, in _apply's order (step's)
        self._new_exec()  # fail early on a model JSBSim cannot load

    # ------------------------------------------------------------------ set-up

    def _new_exec(self) -> None:
        """A fresh FGFDMExec with the model loaded: every reset starts from the same state."""
        # No banner, no load chatter on stdout.
        jsbsim.FGJSBBase().debug_lvl = 0  # type: ignore[no-untyped-call]
        fdm = jsbsim.FGFDMExec(str(_wheel_root()), None)
        fdm.set_debug_level(0)
        if self._own:
            fdm.set_aircraft_path(str(OWN_AIRCRAFT_DIR))
        try:
            loaded = fdm.load_model(self.aircraft)
        except Exception as err:  # jsbsim raises its own error types for bad XML
            msg = f"aircraft {self.aircraft!r}: JSBSim cannot load it: {err}"
            raise AircraftError(msg) from None
        if not loaded:
            msg = f"aircraft {self.aircraft!r}: JSBSim cannot load it"
            raise AircraftError(msg)
        fdm.set_dt(self._dt_s)
        # JSBSim's turbulence draws from a generator owned by this FGFDMExec: seeding it here,
        # on a fresh instance at every reset, makes gusts repeat exactly.
        fdm["simulation/randomseed"] = self._seed
        pm = fdm.get_property_manager()

        def node(name: str) -> Any:
            # Bound property nodes: a read or write costs a C++ call, no path lookup.
            found = pm.get_node(name)
            if found is None:
                msg = f"aircraft {self.aircraft!r}: JSBSim model has no property {name}"
                raise AircraftError(msg)
            return found

        self._getters = tuple(node(p).get_double_value for p in _STATE_PROPERTIES)
        self._set_elevator = node("fcs/elevator-cmd-norm").set_double_value
        self._set_aileron = node("fcs/aileron-cmd-norm").set_double_value
        self._set_rudder = node("fcs/rudder-cmd-norm").set_double_value
        self._set_steer = node("fcs/steer-cmd-norm").set_double_value
        self._set_throttle = node("fcs/throttle-cmd-norm").set_double_value
        self._set_brake_left = node("fcs/left-brake-cmd-norm").set_double_value
        self._set_brake_right = node("fcs/right-brake-cmd-norm").set_double_value
        self._setters = (
            self._set_aileron, self._set_elevator, self._set_rudder, self._set_steer,
            self._set_throttle, self._set_brake_left, self._set_brake_right,
        )  # fmt: skip
        self._set_terrain_ft = node("position/terrain-elevation-asl-ft").set_double_value
        self._run = fdm.run
        self._fdm = fdm

    def reset(self, ground: GeoPoint, initial: InitialCondition, wind: Wind) -> VehicleState:
        """Place the aircraft at rest on the ground or trimmed in level flight; time 0."""
        self._new_exec()
        fdm = self._fdm
        self._ground = ground
        self._ned = _LocalNed(ground)
        self._time_ns = 0
        fdm["ic/lat-geod-deg"] = initial.lat_deg
        fdm["ic/long-gc-deg"] = initial.lon_deg
        fdm["ic/terrain-elevation-ft"] = self._ground_under(initial) * M_FT
        fdm["ic/psi-true-deg"] = math.degrees(initial.heading_rad) % 360.0
        if initial.on_ground:
            self._place_on_ground()
        else:
            self._trim_airborne(initial, wind)
        # JSBSim's run_ic and trim reset the atmosphere's wind to the IC's (none): set it last.
        wind_n, wind_e = _wind_ned_fps(wind)
        fdm["atmosphere/wind-north-fps"] = wind_n
        fdm["atmosphere/wind-east-fps"] = wind_e
        if wind.turbulence > 0.0:
            self._set_turbulence(wind.turbulence)
        self._apply(self.trim_command)
        # One frame with integration suspended updates airspeed etc. without moving time.
        fdm.suspend_integration()
        self._run()
        fdm.resume_integration()
        return self._build_state()

    def _ground_under(self, initial: InitialCondition) -> float:
        """Ground elevation at the start: home's, or the terrain's under the aircraft."""
        if self._terrain is None:
            return self._ground.alt_amsl_m
        return self._terrain.ground_and_surface_at(initial.lat_deg, initial.lon_deg)[0]

    def _place_on_ground(self) -> None:
        fdm = self._fdm
        fdm["ic/h-agl-ft"] = 0.0
        fdm["ic/vt-fps"] = 0.0
        fdm["ic/theta-deg"] = 0.0
        fdm["ic/phi-deg"] = 0.0
        fdm.run_ic()
        self._start_engines()
        # JSBSim's ground trim finds the height and pitch at which the gear carries the weight;
        # should it fail, the settling below still brings the aircraft to rest.
        with contextlib.suppress(Exception), _quiet_stdout():
            fdm.do_trim(2)
        self.trim_command = ActuatorCommand(brake=1.0)
        # Let the gear springs settle with the brakes on (hidden time, not part of the flight).
        self._apply(self.trim_command)
        for _ in range(int(2.0 / self._dt_s)):
            self._run()

    def _start_engines(self) -> None:
        """Engines running, mixture rich (piston aircraft of the wheel need both to go)."""
        fdm = self._fdm
        fdm["propulsion/set-running"] = -1
        pm = fdm.get_property_manager()
        for i in range(16):
            name = f"fcs/mixture-cmd-norm[{i}]"
            if not pm.hasNode(name):
                break
            fdm[name] = 1.0

    def _trim_airborne(self, initial: InitialCondition, wind: Wind) -> None:
        fdm = self._fdm
        alt_agl_m = initial.alt_amsl_m - self._ground_under(initial)
        if alt_agl_m < 1.0 or initial.airspeed_m_s <= 0.0:
            msg = (
                f"air start: altitude {alt_agl_m:.1f} m above ground and airspeed "
                f"{initial.airspeed_m_s} m/s must both be positive"
            )
            raise AircraftError(msg)
        fdm["ic/h-sl-ft"] = initial.alt_amsl_m * M_FT
        fdm["ic/vt-fps"] = initial.airspeed_m_s * M_FT
        fdm["ic/gamma-deg"] = 0.0
        fdm.run_ic()
        self._start_engines()
        try:
            with _quiet_stdout():
                fdm.do_trim(1)  # full trim: throttle, pitch trim, aileron and rudder trims
        except Exception:
            msg = (
                f"aircraft {self.aircraft!r}: cannot trim level flight at "
                f"{initial.airspeed_m_s} m/s (below its stall speed or above its top speed?)"
            )
            raise AircraftError(msg) from None
        if wind.speed_m_s != 0.0:
            self._add_wind_to_trim(wind)
        # Move the trimmed controls from JSBSim's trim inputs into the commands, so that a
        # command means the same (absolute) surface position whatever the start.
        elevator = fdm["fcs/elevator-cmd-norm"] + fdm["fcs/pitch-trim-cmd-norm"]
        aileron = fdm["fcs/aileron-cmd-norm"] + fdm["fcs/roll-trim-cmd-norm"]
        rudder = fdm["fcs/rudder-cmd-norm"] + fdm["fcs/yaw-trim-cmd-norm"]
        fdm["fcs/pitch-trim-cmd-norm"] = 0.0
        fdm["fcs/roll-trim-cmd-norm"] = 0.0
        fdm["fcs/yaw-trim-cmd-norm"] = 0.0
        self.trim_command = ActuatorCommand(
            aileron=aileron,
            elevator=elevator,
            # JSBSim's rudder +1 yaws left; ActuatorCommand's rudder +1 yaws right.
            rudder=-rudder,
            throttle=fdm["fcs/throttle-cmd-norm"],
        )

    def _add_wind_to_trim(self, wind: Wind) -> None:
        """Restart from the calm-air trim with the wind added to the ground velocity.

        JSBSim's trim re-initialises the atmosphere without wind; the same air-relative
        state in a moving air mass is the calm trim moved with the air.
        """
        fdm = self._fdm
        wind_n, wind_e = _wind_ned_fps(wind)
        keep = {
            name: fdm[prop]
            for name, prop in (
                ("vn", "velocities/v-north-fps"),
                ("ve", "velocities/v-east-fps"),
                ("vd", "velocities/v-down-fps"),
                ("phi", "attitude/phi-deg"),
                ("theta", "attitude/theta-deg"),
                ("psi", "attitude/psi-deg"),
                ("h", "position/h-sl-ft"),
            )
        }
        fdm["ic/phi-deg"] = keep["phi"]
        fdm["ic/theta-deg"] = keep["theta"]
        fdm["ic/psi-true-deg"] = keep["psi"]
        fdm["ic/h-sl-ft"] = keep["h"]
        fdm["ic/vn-fps"] = keep["vn"] + wind_n
        fdm["ic/ve-fps"] = keep["ve"] + wind_e
        fdm["ic/vd-fps"] = keep["vd"]
        fdm.run_ic()

    def _set_turbulence(self, intensity: float) -> None:
        """JSBSim's MIL-F-8785C / MIL-HDBK-1797 Dryden gust model, seeded in ``_new_exec``.

        ``intensity`` 0..1 scales the wind speed at 20 ft that sets the low-altitude
        intensity (1 = 45 kt, "severe" in the standard) and the high-altitude probability-of-
        exceedance level (1 = level 6).
        """
        if not intensity <= 1.0:
            msg = f"turbulence {intensity!r}: expected a number in 0..1"
            raise AircraftError(msg)
        fdm = self._fdm
        fdm["atmosphere/turb-type"] = 3  # ttMilspec (Dryden); ttTustin (4) gives NaN in 1.3.3
        fdm["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = 45.0 * 1.68781 * intensity
        fdm["atmosphere/turbulence/milspec/severity"] = max(1, round(6.0 * intensity))

    # ------------------------------------------------------------------ stepping

    def _apply(self, command: ActuatorCommand) -> None:
        self._set_aileron(command.aileron)
        self._set_elevator(command.elevator)
        # JSBSim's rudder +1 yaws left; ActuatorCommand's rudder +1 yaws right.
        self._set_rudder(-command.rudder)
        self._set_steer(command.rudder)
        self._set_throttle(command.throttle)
        self._set_brake_left(command.brake)
        self._set_brake_right(command.brake)

    def step(self, command: ActuatorCommand) -> VehicleState:
        """Apply ``command`` and advance one physics step."""
        # _apply written out (a 200 Hz path): the same properties in the same order.
        aileron, elevator, rudder, steer, throttle, brake_left, brake_right = self._setters
        aileron(command.aileron)
        elevator(command.elevator)
        rudder(-command.rudder)
        steer(command.rudder)
        throttle(command.throttle)
        brake_left(command.brake)
        brake_right(command.brake)
        run = self._run
        if self._substeps == 1:
            run()
        else:
            for _ in range(self._substeps):
                run()
        self._time_ns += self.step_ns
        return self._build_state()

    def _build_state(self) -> VehicleState:
        # A 200 Hz path: geodetic -> NED about _LocalNed's origin and Euler -> quaternion
        # compiled (state_kernel), the state built positionally (state.vehicle_state).
        (
            get_lat, get_lon, get_alt, get_phi, get_theta, get_psi, get_vn, get_ve, get_vd,
            get_p, get_q, get_r, get_fx, get_fy, get_fz, get_vtrue, get_wow,
        ) = self._getters  # fmt: skip
        ft_m = FT_M
        lat = get_lat()
        lon = get_lon()
        alt_m = get_alt() * ft_m
        phi = get_phi()
        theta = get_theta()
        psi = get_psi()
        ground_m: float | None = None
        surface_m: float | None = None
        terrain = self._terrain
        if terrain is not None:
            # The ground the wheels meet during the next step: the terrain under the aircraft.
            ground_m, surface_m = terrain.ground_and_surface_at(lat, lon)
            self._set_terrain_ft(ground_m * M_FT)
        ned, quat, yaw = state_kernel.truth(self._ned.array, lat, lon, alt_m, phi, theta, psi)
        return vehicle_state(
            self._time_ns,
            lat,
            lon,
            alt_m,
            alt_m - self._ground.alt_amsl_m,
            ned,
            quat,
            phi,
            theta,
            yaw,
            (get_vn() * ft_m, get_ve() * ft_m, get_vd() * ft_m),
            (get_p(), get_q(), get_r()),
            (get_fx() * ft_m, get_fy() * ft_m, get_fz() * ft_m),
            get_vtrue() * ft_m,
            get_wow() > 0.5,
            ground_m,
            surface_m,
        )
