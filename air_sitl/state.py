"""Core value types shared by every stage: frozen dataclasses, units in names, no dependencies.

Conventions (SPEC section 2): local frame NED relative to home, body frame FRD, quaternions
Hamilton scalar-first ``(w, x, y, z)`` rotating body to NED, time in integer nanoseconds of
simulation time.
"""

from __future__ import annotations

import enum
from collections.abc import Callable
from dataclasses import MISSING, dataclass, fields
from typing import Any, TypeVar

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]
T = TypeVar("T")


@dataclass(frozen=True, slots=True, kw_only=True)
class GeoPoint:
    """A WGS84 position; altitude above mean sea level."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float


@dataclass(frozen=True, slots=True, kw_only=True)
class VehicleState:
    """Truth state of the aircraft at one simulation instant."""

    sim_time_ns: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    alt_agl_m: float  # above home's ground (the take-off point): AIR's RelativeAltitude
    pos_ned_m: Vec3  # relative to home
    q_body_to_ned_wxyz: Quat  # Hamilton, scalar first
    roll_rad: float
    pitch_rad: float
    yaw_rad: float  # heading, 0 = north, clockwise positive, in [-pi, pi)
    vel_ned_m_s: Vec3
    rate_frd_rad_s: Vec3  # body angular rates p, q, r
    specific_force_frd_m_s2: Vec3  # what an accelerometer measures (about (0,0,-9.81) at rest)
    airspeed_m_s: float  # true airspeed
    on_ground: bool
    # With a surface model (--dem): the heights AMSL under the aircraft of the ground its
    # wheels meet and of the first surface seen from above (roofs, canopy); None: flat ground
    # at home's elevation.
    ground_amsl_m: float | None = None
    surface_amsl_m: float | None = None

    @property
    def surface_agl_m(self) -> float:
        """Height above the surface under the aircraft (without one: above home's ground)."""
        if self.surface_amsl_m is None:
            return self.alt_agl_m
        return self.alt_amsl_m - self.surface_amsl_m


@dataclass(frozen=True, slots=True, kw_only=True)
class ActuatorCommand:
    """Normalised control inputs to the flight model.

    ``aileron`` positive rolls right, ``elevator`` positive pitches nose DOWN (JSBSim's
    convention), ``rudder`` positive yaws right (and steers the nose wheel right),
    ``throttle`` and ``brake`` in [0, 1].
    """

    aileron: float = 0.0
    elevator: float = 0.0
    rudder: float = 0.0
    throttle: float = 0.0
    brake: float = 0.0  # wheel brakes, 0 (off) to 1 (full); ignored by aircraft without brakes


class FlightMode(enum.Enum):
    """What the autopilot is doing; mapped to PX4 main/sub modes by the MAVLink layer."""

    IDLE = "idle"  # on the ground, disarmed or armed and waiting
    TAKEOFF = "takeoff"
    MISSION = "mission"
    LOITER = "loiter"  # hold: circle the current point
    RTL = "rtl"
    LAND = "land"


@dataclass(frozen=True, slots=True, kw_only=True)
class AutopilotStatus:
    """The autopilot's externally visible state after one update."""

    mode: FlightMode
    armed: bool
    current_seq: int  # index of the active mission item, -1 when none
    capturing: bool  # inside the capture window (IMAGE_START..STOP, or AIR's default window)
    mission_completed: bool  # the last navigation item is done
    reached_seq: int = -1  # item reached during this update, -1 when none
    # Path-tracking errors of guidance (NaN when not on a straight leg or loiter circle).
    cross_track_m: float = float("nan")
    alt_error_m: float = float("nan")
    tracking_settled: bool = False  # 10 s or more since the turn onto the current leg/circle


@dataclass(frozen=True, slots=True, kw_only=True)
class ImuSample:
    """One reading of the simulated IMU/AHRS (with noise, bias and drift)."""

    sim_time_ns: int
    gyro_frd_rad_s: Vec3
    accel_frd_m_s2: Vec3  # specific force
    q_ahrs_body_to_ned_wxyz: Quat  # the attitude the on-board filter reports


@dataclass(frozen=True, slots=True, kw_only=True)
class GpsFix:
    """One reading of the simulated GNSS receiver."""

    sim_time_ns: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_ned_m_s: Vec3
    fix_type: int  # 0 none, 3 = 3D fix (MAVLink GPS_FIX_TYPE)
    satellites: int
    eph_m: float
    epv_m: float


@dataclass(frozen=True, slots=True, kw_only=True)
class BatteryState:
    """The propulsion battery after one step (:mod:`air_sitl.battery`)."""

    voltage_v: float  # at the terminals, under load (sags with current)
    current_a: float
    consumed_mah: float
    consumed_wh: float
    remaining: float  # 1.0 full .. 0.0 empty (of the capacity)


@dataclass(frozen=True, slots=True, kw_only=True)
class NavFlags:
    """Which parts of the estimate are valid, and which sources feed it (ESTIMATOR_STATUS)."""

    attitude: bool
    velocity_horiz: bool
    velocity_vert: bool
    pos_horiz_rel: bool
    pos_horiz_abs: bool
    pos_vert_abs: bool
    gnss_fusing: bool
    aid_fusing: bool
    dead_reckoning: bool  # no absolute horizontal position source fusing
    wind_estimated: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class NavEstimate:
    """The onboard estimate at the current time (output predictor, not the delayed state)."""

    sim_time_ns: int
    pos_ned_m: Vec3  # relative to home
    vel_ned_m_s: Vec3
    q_body_to_ned_wxyz: Quat
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    std_h_m: float  # sqrt of the larger eigenvalue of the horizontal position covariance
    std_v_m: float
    wind_ned_m_s: tuple[float, float]  # horizontal wind (where the air moves to), north, east
    gyro_bias_rad_s: Vec3
    accel_bias_m_s2: Vec3
    flags: NavFlags


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraTick:
    """A camera exposure at this physics step (the runner decides them, for every sink)."""

    index: int  # the camera's frame index: what the FrameSource renders, the bus's ``frame``
    # Index within the capture window (the archive's frame); None outside it (with an aid the
    # camera runs for the whole flight: those frames are not archived).
    capture_index: int | None


@dataclass(frozen=True, slots=True, kw_only=True)
class SimSample:
    """Everything produced at one physics step; what sinks receive."""

    state: VehicleState
    autopilot: AutopilotStatus
    imu: ImuSample
    gps: GpsFix | None  # None between GPS updates or while GPS is denied
    # The onboard estimate the autopilot flew on (``--nav ekf``); None with ``--nav truth``.
    nav: NavEstimate | None = None
    actuators: ActuatorCommand | None = None  # what the autopilot commanded for this step
    battery: BatteryState | None = None
    camera: CameraTick | None = None  # a camera exposure at this step, None between them


def mission_sample(
    state: VehicleState, *, capturing: bool = True, current_seq: int = 1
) -> SimSample:
    """A SimSample of ``state`` armed in a mission, with an ideal IMU and no GPS update
    (previews, tests, benchmarks: what the camera and the sinks need around a pose)."""
    return SimSample(
        state=state,
        autopilot=AutopilotStatus(
            mode=FlightMode.MISSION,
            armed=True,
            current_seq=current_seq,
            capturing=capturing,
            mission_completed=False,
        ),
        imu=ImuSample(
            sim_time_ns=state.sim_time_ns,
            gyro_frd_rad_s=state.rate_frd_rad_s,
            accel_frd_m_s2=state.specific_force_frd_m_s2,
            q_ahrs_body_to_ned_wxyz=state.q_body_to_ned_wxyz,
        ),
        gps=None,
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraFrame:
    """One rendered camera frame with the pose it was taken from."""

    # The camera's 0-based frame index: within the capture window, or of the whole flight when
    # the camera stays on for an aid (``sample.camera`` then tells the capture index, or None).
    index: int
    sim_time_ns: int
    jpeg: bytes
    width_px: int
    height_px: int
    sample: SimSample  # the physics sample at the exposure instant
    map_xy_px: tuple[int, int]  # where the image-centre ray meets the map, in map pixels
    # Share of the image showing the map's nodata or ground off the map (0.0: none).
    nodata_fraction: float = 0.0


def positional_builder(cls: type[T]) -> Callable[..., T]:
    """A function building ``cls`` (a frozen dataclass with slots) from all its fields given
    positionally in declared order: the same object as ``cls(...)``, three times faster.

    The frozen ``__init__`` sets each field through ``object.__setattr__`` (a generic call
    per field: most of the cost of the values built at every 200 Hz step). Here a plain twin
    class with the same slots is filled by ordinary attribute stores and then becomes a ``cls``
    (``__class__`` assignment, allowed between classes of identical layout). The twin's
    ``__init__`` is generated from the fields, as dataclasses generates its own.
    """
    params, body = [], []
    namespace: dict[str, Any] = {"_cls": cls}
    for f in fields(cls):  # type: ignore[arg-type]
        if f.default is MISSING:
            params.append(f.name)
        else:
            namespace[f"_default_{f.name}"] = f.default
            params.append(f"{f.name}=_default_{f.name}")
        body.append(f"    self.{f.name} = {f.name}\n")
    slots = cls.__slots__  # type: ignore[attr-defined]
    namespace["_twin"] = type(f"_Writable{cls.__name__}", (), {"__slots__": slots})
    code = (
        f"def build({', '.join(params)}):\n    self = _twin()\n{''.join(body)}"
        "    self.__class__ = _cls\n    return self\n"
    )
    exec(code, namespace)  # generated from the dataclass's own fields, as dataclasses does
    built: Callable[..., T] = namespace["build"]
    return built


# The values of every 200 Hz physics step, built positionally (fields in declared order).
vehicle_state: Callable[..., VehicleState] = positional_builder(VehicleState)
sim_sample: Callable[..., SimSample] = positional_builder(SimSample)
imu_sample: Callable[..., ImuSample] = positional_builder(ImuSample)
actuator_command: Callable[..., ActuatorCommand] = positional_builder(ActuatorCommand)
battery_state: Callable[..., BatteryState] = positional_builder(BatteryState)
autopilot_status: Callable[..., AutopilotStatus] = positional_builder(AutopilotStatus)
camera_tick: Callable[..., CameraTick] = positional_builder(CameraTick)  # 50 Hz
