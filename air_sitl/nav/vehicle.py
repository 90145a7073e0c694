"""The estimate as a VehicleState: what the autopilot and telemetry take, from the filter.

The closed loop (SPEC section 6) steers on the onboard estimate, not on the truth; the
autopilot and the MAVLink telemetry read a :class:`~air_sitl.state.VehicleState`, so the
estimate is presented as one: position, velocity and attitude from the filter, body rates and
specific force from the IMU minus the estimated biases, airspeed from the airspeed sensor.
"""

from __future__ import annotations

from air_sitl.frames import quat2euler
from air_sitl.state import ImuSample, NavEstimate, VehicleState


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
    return VehicleState(
        sim_time_ns=estimate.sim_time_ns,
        lat_deg=estimate.lat_deg,
        lon_deg=estimate.lon_deg,
        alt_amsl_m=estimate.alt_amsl_m,
        alt_agl_m=estimate.alt_amsl_m - home_alt_amsl_m,
        pos_ned_m=estimate.pos_ned_m,
        q_body_to_ned_wxyz=estimate.q_body_to_ned_wxyz,
        roll_rad=roll,
        pitch_rad=pitch,
        yaw_rad=yaw,
        vel_ned_m_s=estimate.vel_ned_m_s,
        rate_frd_rad_s=(g[0] - bg[0], g[1] - bg[1], g[2] - bg[2]),
        specific_force_frd_m_s2=(f[0] - ba[0], f[1] - ba[1], f[2] - ba[2]),
        airspeed_m_s=airspeed_m_s,
        on_ground=on_ground,
    )
