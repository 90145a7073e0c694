"""Constructed truth states for tests: VehicleStates whose attitude fields agree."""

from __future__ import annotations

from air_sitl.camera.render import pose_state
from air_sitl.frames import euler2quat
from air_sitl.state import GeoPoint, Vec3, VehicleState


def airborne_state(
    t_ns: int,
    *,
    lat_deg: float,
    lon_deg: float,
    alt_amsl_m: float,
    alt_agl_m: float,
    pos_ned_m: Vec3,
    rpy_rad: Vec3 = (0.0, 0.0, 0.0),
    vel_ned_m_s: Vec3 = (15.0, 0.0, 0.0),
    rate_frd_rad_s: Vec3 = (0.0, 0.0, 0.0),
    specific_force_frd_m_s2: Vec3 = (0.0, 0.0, -9.81),
    airspeed_m_s: float = 15.0,
) -> VehicleState:
    """A flying aircraft at ``t_ns``; the quaternion is made from ``rpy_rad`` (roll, pitch, yaw)."""
    roll, pitch, yaw = rpy_rad
    return VehicleState(
        sim_time_ns=t_ns,
        lat_deg=lat_deg,
        lon_deg=lon_deg,
        alt_amsl_m=alt_amsl_m,
        alt_agl_m=alt_agl_m,
        pos_ned_m=pos_ned_m,
        q_body_to_ned_wxyz=euler2quat(roll, pitch, yaw),
        roll_rad=roll,
        pitch_rad=pitch,
        yaw_rad=yaw,
        vel_ned_m_s=vel_ned_m_s,
        rate_frd_rad_s=rate_frd_rad_s,
        specific_force_frd_m_s2=specific_force_frd_m_s2,
        airspeed_m_s=airspeed_m_s,
        on_ground=False,
    )


def above(
    home: GeoPoint,
    alt_agl_m: float,
    *,
    roll_rad: float = 0.0,
    pitch_rad: float = 0.0,
    yaw_rad: float = 0.0,
) -> VehicleState:
    """A still pose ``alt_agl_m`` straight above ``home`` (camera and map tests)."""
    return pose_state(
        home.lat_deg,
        home.lon_deg,
        home.alt_amsl_m + alt_agl_m,
        alt_agl_m=alt_agl_m,
        roll_rad=roll_rad,
        pitch_rad=pitch_rad,
        yaw_rad=yaw_rad,
    )
