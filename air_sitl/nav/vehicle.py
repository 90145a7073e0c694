"""The estimate as a VehicleState: what the autopilot and telemetry take, from the filter.

The closed loop (SPEC section 6) steers on the onboard estimate, not on the truth; the
autopilot and the MAVLink telemetry read a :class:`~air_sitl.state.VehicleState`, so the
estimate is presented as one: position, velocity and attitude from the filter, body rates and
specific force from the IMU minus the estimated biases, airspeed from the airspeed sensor.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import MISSING, fields
from typing import Any, TypeVar

from air_sitl.frames import quat2euler
from air_sitl.state import ImuSample, NavEstimate, VehicleState

T = TypeVar("T")


def positional_builder(cls: type[T]) -> Callable[..., T]:
    """A function building ``cls`` (a frozen dataclass with slots) from all its fields given
    positionally in declared order: the same object as ``cls(...)``, three times faster.

    The frozen ``__init__`` sets each field through ``object.__setattr__`` (a generic call
    per field: most of the cost of one VehicleState per 200 Hz step). Here a plain twin class
    with the same slots is filled by ordinary attribute stores and then becomes a ``cls``
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


# One VehicleState per 200 Hz step (the estimate the autopilot flies on), one NavEstimate
# per filter period.
vehicle_state: Callable[..., VehicleState] = positional_builder(VehicleState)
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
