"""Barometer, airspeed sensor and magnetometer heading: truth in, noisy measurement out.

Pure, seeded classes in the style of :mod:`air_sitl.sensors` (which another change owns now;
these move there later). Call ``sample(state)`` once per physics step, in order: a reading
comes back at the sensor's rate, else None. Nothing here reads the wall clock.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from air_sitl.frames import wrap_pi
from air_sitl.nav.types import AirspeedSample, BaroSample, HeadingSample
from air_sitl.state import VehicleState

NS_PER_S = 1_000_000_000


class _Draws:
    """Standard normal rows from pre-drawn blocks of a seeded PCG64 (fast and deterministic)."""

    __slots__ = ("_block", "_i", "_rng", "_width")

    def __init__(self, seed: int, salt: int, width: int) -> None:
        self._rng = np.random.default_rng(np.random.SeedSequence([seed, salt]))
        self._width = width
        self._block: list[list[float]] = []
        self._i = 0

    def first(self) -> list[float]:
        """One row drawn before the per-sample stream (turn-on offsets)."""
        return self.row()

    def row(self) -> list[float]:
        if self._i >= len(self._block):
            self._block = self._rng.standard_normal((1024, self._width)).tolist()
            self._i = 0
        self._i += 1
        return self._block[self._i - 1]


@dataclass(frozen=True, slots=True, kw_only=True)
class BaroNoise:
    """A MEMS barometer (MS5611-like) as pressure altitude, 1-sigma."""

    rate_hz: float = 20.0
    noise_m: float = 0.5  # white noise per reading
    offset_m: float = 2.0  # turn-on offset (weather, QNH error), drawn once
    drift_m_sqrt_s: float = 0.02  # slow random walk (temperature, weather)


class Barometer:
    """Pressure altitude AMSL = truth + turn-on offset + random-walk drift + white noise."""

    def __init__(self, *, seed: int, noise: BaroNoise | None = None) -> None:
        self.noise = noise or BaroNoise()
        self.period_ns = round(NS_PER_S / self.noise.rate_hz)
        self._draws = _Draws(seed, 0xBA50, 2)
        self.drift_m = self._draws.first()[0] * self.noise.offset_m
        self._walk = self.noise.drift_m_sqrt_s * math.sqrt(self.period_ns / NS_PER_S)

    def sample(self, state: VehicleState) -> BaroSample | None:
        if state.sim_time_ns % self.period_ns:
            return None
        z = self._draws.row()
        self.drift_m += z[0] * self._walk
        return BaroSample(
            sim_time_ns=state.sim_time_ns,
            alt_amsl_m=state.alt_amsl_m + self.drift_m + z[1] * self.noise.noise_m,
        )


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
        self._draws = _Draws(seed, 0xA125, 1)
        self.scale = 1.0 + self._draws.first()[0] * self.noise.scale_error

    def sample(self, state: VehicleState) -> AirspeedSample | None:
        if state.sim_time_ns % self.period_ns:
            return None
        z = self._draws.row()
        value = state.airspeed_m_s * self.scale + z[0] * self.noise.noise_m_s
        return AirspeedSample(sim_time_ns=state.sim_time_ns, airspeed_m_s=max(0.0, value))


@dataclass(frozen=True, slots=True, kw_only=True)
class MagNoise:
    """A magnetometer used as a compass (heading only), 1-sigma."""

    rate_hz: float = 10.0
    noise_rad: float = 0.03
    offset_rad: float = 0.02  # residual hard/soft-iron heading error, drawn once
    drift_rad_sqrt_s: float = 0.002  # slow random walk (motor currents, temperature)
    declination_rad: float = 0.0  # magnetic north east of true north


class Magnetometer:
    """Magnetic heading = truth yaw - declination + offset + drift + white noise, wrapped."""

    def __init__(self, *, seed: int, noise: MagNoise | None = None) -> None:
        self.noise = noise or MagNoise()
        self.period_ns = round(NS_PER_S / self.noise.rate_hz)
        self._draws = _Draws(seed, 0x3A6, 2)
        self.error_rad = self._draws.first()[0] * self.noise.offset_rad
        self._walk = self.noise.drift_rad_sqrt_s * math.sqrt(self.period_ns / NS_PER_S)

    def sample(self, state: VehicleState) -> HeadingSample | None:
        if state.sim_time_ns % self.period_ns:
            return None
        z = self._draws.row()
        self.error_rad += z[0] * self._walk
        n = self.noise
        heading = state.yaw_rad - n.declination_rad + self.error_rad + z[1] * n.noise_rad
        return HeadingSample(sim_time_ns=state.sim_time_ns, heading_rad=wrap_pi(heading))
