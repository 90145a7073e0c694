"""Onboard navigation: an error-state EKF fed by the simulated IMU, GNSS, barometer, airspeed,
magnetic heading and external position aids, fused on a delayed horizon (PX4 EKF2's design).

State (``ekf``): position and velocity NED from home, attitude body->NED, gyro and
accelerometer biases, horizontal wind; 17 error states with a global attitude error (Sola
2017). The IMU is summed into 20 ms deltas for the nominal state and the covariance is
propagated every 80 ms. Every source has a module deciding when to start, fuse, reset and
stop it: ``gnss`` (horizontal position and 3-D velocity), ``baro`` (the height reference, its
offset calibrated against GNSS), ``airspeed`` (true airspeed and synthetic zero sideslip:
wind), ``mag`` (heading), ``aid`` (external horizontal positions, one control per name). The
numerics are compiled: ``strapdown`` (the delayed state's prediction, the output predictor
and its ring of IMU deltas), ``kernels`` (the covariance step, each measurement model with its
gated update), ``quaternion``; ``fusion`` reads an update's outcome, ``buffer`` holds each
source's measurements until the delayed horizon reaches them, ``status`` the counters,
``filter`` is the public :class:`NavFilter`::

    nav = NavFilter(home)                        # NavParams() defaults
    for sample in flight:                        # every 5 ms physics step
        if sample.gps is not None:
            nav.fuse_gnss(sample.gps)            # also fuse_baro, fuse_airspeed, fuse_heading
        nav.predict(sample.imu)
        estimate = nav.estimate()                # NavEstimate at the newest IMU time
    nav.fuse_aid(AidMeasurement(name="map", sim_time_ns=t, position=(east, north, up)), now_ns)
    nav.status().to_json()                       # counters for summary.json's "nav" block

``vehicle.estimated_state`` presents the estimate as the VehicleState the autopilot and the
telemetry read. Barometer, airspeed sensor and magnetometer models live in ``sensors_extra``
for now.
"""

from air_sitl.nav.filter import NavFilter
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import AidStatus, NavStatus
from air_sitl.nav.types import (
    AidFrame,
    AidMeasurement,
    AidResult,
    AirspeedSample,
    BaroSample,
    HeadingSample,
)
from air_sitl.nav.vehicle import estimated_state
from air_sitl.state import NavEstimate, NavFlags  # the filter's output, a core value type

__all__ = [
    "AidFrame",
    "AidMeasurement",
    "AidResult",
    "AidStatus",
    "AirspeedSample",
    "BaroSample",
    "HeadingSample",
    "NavEstimate",
    "NavFilter",
    "NavFlags",
    "NavParams",
    "NavStatus",
    "estimated_state",
]
