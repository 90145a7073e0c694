"""The estimate as a VehicleState: what the autopilot and telemetry take, from the filter.

The closed loop (SPEC section 6) steers on the onboard estimate, not on the truth; the
autopilot and the MAVLink telemetry read a :class:`~air_sitl.state.VehicleState`, so the
estimate is presented as one: position, velocity and attitude from the filter, body rates and
specific force from the IMU minus the estimated biases, airspeed from the airspeed sensor.
"""

from __future__ import annotations

from dataclasses import fields

from air_sitl.frames import quat2euler
from air_sitl.state import ImuSample, NavEstimate, Quat, Vec3, VehicleState

# One VehicleState per 200 Hz step: the frozen dataclass __init__ sets each field through
# object.__setattr__ (a bound-method lookup and a generic setattr each, half the cost of the
# whole construction); writing the slots directly builds the same object twice as fast.
_SLOT_SETTERS = tuple(getattr(VehicleState, f.name).__set__ for f in fields(VehicleState))
_new = object.__new__


def vehicle_state(
    sim_time_ns: int,
    lat_deg: float,
    lon_deg: float,
    alt_amsl_m: float,
    alt_agl_m: float,
    pos_ned_m: Vec3,
    q_body_to_ned_wxyz: Quat,
    roll_rad: float,
    pitch_rad: float,
    yaw_rad: float,
    vel_ned_m_s: Vec3,
    rate_frd_rad_s: Vec3,
    specific_force_frd_m_s2: Vec3,
    airspeed_m_s: float,
    on_ground: bool,
    ground_amsl_m: float | None = None,
    surface_amsl_m: float | None = None,
) -> VehicleState:
    """``VehicleState(...)`` with the fields in their declared order, built without the frozen
    __init__ (equal to the one it would build: a test pins the order)."""
    state: VehicleState = _new(VehicleState)
    values = (
        sim_time_ns, lat_deg, lon_deg, alt_amsl_m, alt_agl_m, pos_ned_m, q_body_to_ned_wxyz,
        roll_rad, pitch_rad, yaw_rad, vel_ned_m_s, rate_frd_rad_s, specific_force_frd_m_s2,
        airspeed_m_s, on_ground, ground_amsl_m, surface_amsl_m,
    )  # fmt: skip
    for setter, value in zip(_SLOT_SETTERS, values, strict=True):
        setter(state, value)
    return state


def estimated_state(
    estimate: NavEstimate,
    imu: ImuSample,
    *,
    airspeed_m_s: float,
    on_ground: bool,
    home_alt_amsl_m: float,
) -> VehicleState:
    """A VehicleState built from the filter's estimate and the latest IMU and airspeed."""
    roll, pitch, yaw = quat2euler(estimate.q_body_to_ned_wxyz)
    g, bg = imu.gyro_frd_rad_s, estimate.gyro_bias_rad_s
    f, ba = imu.accel_frd_m_s2, estimate.accel_bias_m_s2
    return vehicle_state(
        estimate.sim_time_ns,
        estimate.lat_deg,
        estimate.lon_deg,
        estimate.alt_amsl_m,
        estimate.alt_amsl_m - home_alt_amsl_m,
        estimate.pos_ned_m,
        estimate.q_body_to_ned_wxyz,
        roll,
        pitch,
        yaw,
        estimate.vel_ned_m_s,
        (g[0] - bg[0], g[1] - bg[1], g[2] - bg[2]),
        (f[0] - ba[0], f[1] - ba[1], f[2] - ba[2]),
        airspeed_m_s,
        on_ground,
    )
