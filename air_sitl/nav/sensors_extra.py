"""Barometer, airspeed sensor and magnetometer heading: truth in, noisy measurement out.

Pure, seeded classes in the style of :mod:`air_sitl.sensors` (which another change owns now;
these move there later). Call ``sample(state)`` once per physics step, in order: a reading
comes back at the sensor's rate, else None. Nothing here reads the wall clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from air_sitl.clock import NS_PER_S
from air_sitl.frames import wrap_pi
from air_sitl.nav.types import AirspeedSample, BaroSample, HeadingSample
from air_sitl.sensors import NormalRows
from air_sitl.state import VehicleState, positional_builder

R = TypeVar("R")  # a sensor's reading
# The readings, built positionally (fields in declared order: time, value), 40 a second.
_baro_sample = positional_builder(BaroSample)
_airspeed_sample = positional_builder(AirspeedSample)
_heading_sample = positional_builder(HeadingSample)


def _draws(seed: int, salt: int, width: int) -> NormalRows:
    """The normal rows of one sensor: its own stream of the flight's seed."""
    return NormalRows(np.random.default_rng(np.random.SeedSequence([seed, salt])), width)


class _DriftingSensor(Generic[R]):
    """A reading every ``period_ns``: truth with an error of a turn-on offset (drawn once), a
    random walk and white noise (two normal draws a reading)."""

    def __init__(
        self, seed: int, salt: int, rate_hz: float, offset: float, drift_sqrt_s: float, noise: float
    ) -> None:
        self.period_ns = round(NS_PER_S / rate_hz)
        self._draws = _draws(seed, salt, 2)
        self.drift = self._draws.row()[0] * offset
        self._walk = drift_sqrt_s * math.sqrt(self.period_ns / NS_PER_S)
        self._noise = noise

    def sample(self, state: VehicleState) -> R | None:
        if state.sim_time_ns % self.period_ns:
            return None
        z = self._draws.row()
        self.drift += z[0] * self._walk
        return self._reading(state, self.drift, z[1] * self._noise)

    def _reading(self, state: VehicleState, drift: float, white: float) -> R:
        raise NotImplementedError


@dataclass(frozen=True, slots=True, kw_only=True)
class BaroNoise:
    """A MEMS barometer (MS5611-like) as pressure altitude, 1-sigma."""

    rate_hz: float = 20.0
    noise_m: float = 0.5  # white noise per reading
    offset_m: float = 2.0  # turn-on offset (weather, QNH error), drawn once
    drift_m_sqrt_s: float = 0.02  # slow random walk (temperature, weather)


class Barometer(_DriftingSensor[BaroSample]):
    """Pressure altitude AMSL = truth + turn-on offset + random-walk drift + white noise."""

    def __init__(self, *, seed: int, noise: BaroNoise | None = None) -> None:
        self.noise = n = noise or BaroNoise()
        super().__init__(seed, 0xBA50, n.rate_hz, n.offset_m, n.drift_m_sqrt_s, n.noise_m)

    def _reading(self, state: VehicleState, drift: float, white: float) -> BaroSample:
        alt_m = state.alt_amsl_m + drift + white
        return _baro_sample(state.sim_time_ns, alt_m)


@dataclass(frozen=True, slots=True, kw_only=True)
class AirspeedNoise:
    """A differential-pressure airspeed sensor, 1-sigma."""

    rate_hz: float = 10.0
    noise_m_s: float = 0.3
    scale_error: float = 0.02  # calibration scale factor error, drawn once


class AirspeedSensor:
    """True airspeed x (1 + scale error) + white noise, never negative."""

    def __init__(self, *, seed: int, noise: AirspeedNoise | None = None) -> None:
        self.noise = noise or AirspeedNoise()
        self.period_ns = round(NS_PER_S / self.noise.rate_hz)
        self._draws = _draws(seed, 0xA125, 1)
        self.scale = 1.0 + self._draws.row()[0] * self.noise.scale_error

    def sample(self, state: VehicleState) -> AirspeedSample | None:
        if state.sim_time_ns % self.period_ns:
            return None
        z = self._draws.row()
        value = state.airspeed_m_s * self.scale + z[0] * self.noise.noise_m_s
        return _airspeed_sample(state.sim_time_ns, max(0.0, value))


@dataclass(frozen=True, slots=True, kw_only=True)
class MagNoise:
    """A magnetometer used as a compass (heading only), 1-sigma."""

    rate_hz: float = 10.0
    noise_rad: float = 0.03
    offset_rad: float = 0.02  # residual hard/soft-iron heading error, drawn once
    drift_rad_sqrt_s: float = 0.002  # slow random walk (motor currents, temperature)
    declination_rad: float = 0.0  # magnetic north east of true north


class Magnetometer(_DriftingSensor[HeadingSample]):
    """Magnetic heading = truth yaw - declination + offset + drift + white noise, wrapped."""

    def __init__(self, *, seed: int, noise: MagNoise | None = None) -> None:
        self.noise = n = noise or MagNoise()
        super().__init__(seed, 0x3A6, n.rate_hz, n.offset_rad, n.drift_rad_sqrt_s, n.noise_rad)

    def _reading(self, state: VehicleState, drift: float, white: float) -> HeadingSample:
        heading = state.yaw_rad - self.noise.declination_rad + drift + white
        return _heading_sample(state.sim_time_ns, wrap_pi(heading))
