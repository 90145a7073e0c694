"""The estimate as a VehicleState: what the autopilot and telemetry take, from the filter.

The closed loop (SPEC section 6) steers on the onboard estimate, not on the truth; the
autopilot and the MAVLink telemetry read a :class:`~air_sitl.state.VehicleState`, so the
estimate is presented as one: position, velocity and attitude from the filter, body rates and
specific force from the IMU minus the estimated biases, airspeed from the airspeed sensor.
"""

from __future__ import annotations

from collections.abc import Callable

from air_sitl.frames import quat2euler
from air_sitl.state import ImuSample, NavEstimate, VehicleState, positional_builder, vehicle_state

# One NavEstimate per filter period (the VehicleState the autopilot flies on: state.py's).
nav_estimate: Callable[..., NavEstimate] = positional_builder(NavEstimate)


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
