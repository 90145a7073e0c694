"""Measurements the archive does not hold, modelled from truth with a seed (offline driver).

AIR-style archives record no barometer, and their airspeed column is truth. So that methods
still get what a real aircraft's sensors would give, the offline driver derives both from the
truth of ``frames.csv`` with these seeded models; the IMU and AHRS come from ``imu.csv`` and
the GNSS fixes from ``frames.csv`` as recorded (already noisy). The bus publishes neither a
barometer nor an airspeed: there the observations carry ``None`` (see
:mod:`air_sitl.localize.online`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from air_sitl.frames import geodetic2ned
from air_sitl.localize.base import GnssFix
from air_sitl.state import GeoPoint

Array = npt.NDArray[np.float64]

# Sub-streams of one --seed, so that each model draws the same numbers whatever the others do.
_BARO_STREAM = 0xBA20
_AIRSPEED_STREAM = 0xA125


@dataclass(frozen=True, slots=True, kw_only=True)
class BaroModel:
    """Barometric height above home: white noise plus a slow random-walk drift.

    Defaults: a MEMS barometer (MS5611 class) at 50 Hz: about 0.5 m of noise, and drift from
    weather and temperature of a few decimetres per minute.
    """

    noise_m: float = 0.5
    drift_m_sqrt_s: float = 0.05  # random walk: about 0.4 m after a minute, 1.3 m after ten

    def sample(self, truth_rel_m: Array, times_ns: npt.NDArray[np.int64], seed: int) -> Array:
        """Measurements at ``times_ns`` of the truth heights ``truth_rel_m`` (same length)."""
        rng = np.random.default_rng([seed, _BARO_STREAM])
        n = len(truth_rel_m)
        dt_s = np.diff(times_ns.astype(np.float64), prepend=float(times_ns[0]) if n else 0.0) * 1e-9
        walk = np.cumsum(rng.standard_normal(n) * self.drift_m_sqrt_s * np.sqrt(np.abs(dt_s)))
        out: Array = truth_rel_m + walk + rng.standard_normal(n) * self.noise_m
        return out


@dataclass(frozen=True, slots=True, kw_only=True)
class AirspeedModel:
    """Pitot true airspeed: white noise (a differential-pressure sensor at cruise speed)."""

    noise_m_s: float = 0.3

    def sample(self, truth_m_s: Array, seed: int) -> Array:
        """Measurements of the truth airspeeds."""
        rng = np.random.default_rng([seed, _AIRSPEED_STREAM])
        out: Array = np.maximum(truth_m_s + rng.standard_normal(len(truth_m_s)) * self.noise_m_s, 0)
        return out


def fix_position_ned(fix: GnssFix, home: GeoPoint, t_ns: int) -> tuple[float, float, float]:
    """Where a fix puts the aircraft at ``t_ns`` (NED from home): moved on by its velocity."""
    n, e, d = geodetic2ned(
        fix.lat_deg, fix.lon_deg, fix.alt_amsl_m, home.lat_deg, home.lon_deg, home.alt_amsl_m
    )
    dt = (t_ns - fix.sim_time_ns) * 1e-9
    v = fix.vel_ned_m_s
    return (n + v[0] * dt, e + v[1] * dt, d + v[2] * dt)
