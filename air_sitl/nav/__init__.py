"""Onboard navigation: an error-state EKF fed by the simulated IMU, GNSS, barometer, airspeed,
magnetic heading and external position aids, fused on a delayed horizon (PX4 EKF2's design).

``ekf`` holds the state and prediction, ``fusion`` the one gated update every source uses,
one module per aiding source decides when to start, fuse, reset and stop it (``gnss``,
``baro``, ``airspeed``, ``mag``, ``aid``), ``buffer`` the delayed horizon and output
predictor, ``status`` the counters, ``filter`` the public :class:`NavFilter`.
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
    NavEstimate,
    NavFlags,
)

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
]
