"""Propulsion battery of an electric UAV: energy drawn by the motor and avionics, voltage sag.

Pure: the throttle commanded and the airspeed flown go in, a :class:`BatteryState` comes out.
The motor's shaft power grows with the cube of throttle (propeller power at a given airspeed
goes with rpm cubed); the electrical power adds the avionics and divides by the drive
efficiency. The open-circuit voltage falls linearly from full to empty cell voltage with the
charge used; the terminal voltage sags by the current times the internal resistance
(V = Voc - I R with P = V I). Parameters are PX4's (BAT1_*), read live from the store.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from air_sitl.state import BatteryState, battery_state

NS_PER_S = 1_000_000_000
MOTOR_MAX_POWER_W = 600.0  # shaft power at full throttle (a 2-3 kg fixed wing)
AVIONICS_POWER_W = 6.0  # autopilot, GNSS, radio, camera
DRIVE_EFFICIENCY = 0.8  # ESC and motor
_isfinite, _sqrt = math.isfinite, math.sqrt


@dataclass(frozen=True, slots=True, kw_only=True)
class BatterySpec:
    """The pack: PX4's BAT1_CAPACITY, BAT1_N_CELLS, BAT1_V_CHARGED, BAT1_V_EMPTY,
    BAT1_R_INTERNAL."""

    capacity_mah: float = 5000.0
    cells: int = 4
    v_charged_cell: float = 4.05
    v_empty_cell: float = 3.5
    r_internal_ohm: float = 0.02

    @classmethod
    def from_params(cls, get: Callable[[str], float]) -> BatterySpec:
        """From a parameter store's ``get``."""
        return cls(
            capacity_mah=max(1.0, get("BAT1_CAPACITY")),
            cells=max(1, round(get("BAT1_N_CELLS"))),
            v_charged_cell=get("BAT1_V_CHARGED"),
            v_empty_cell=min(get("BAT1_V_EMPTY"), get("BAT1_V_CHARGED")),
            r_internal_ohm=max(0.0, get("BAT1_R_INTERNAL")),
        )


class VersionedParams(Protocol):
    """A parameter store whose ``version`` changes on every change (ParamStore)."""

    version: int

    def get(self, name: str) -> float: ...


def live_spec(params: VersionedParams) -> Callable[[], BatterySpec]:
    """The pack as the parameters say now, rebuilt only when they change (read every step)."""
    cached: tuple[int, BatterySpec] | None = None

    def spec() -> BatterySpec:
        nonlocal cached
        if cached is None or cached[0] != params.version:
            cached = (params.version, BatterySpec.from_params(params.get))
        return cached[1]

    return spec


def electrical_power_w(throttle: float) -> float:
    """Power drawn from the pack at ``throttle`` (0..1)."""
    t = min(1.0, max(0.0, throttle)) if math.isfinite(throttle) else 0.0
    return AVIONICS_POWER_W + MOTOR_MAX_POWER_W * t**3 / DRIVE_EFFICIENCY


def terminal_voltage_v(open_circuit_v: float, r_ohm: float, power_w: float) -> float:
    """Terminal voltage delivering ``power_w`` (V = Voc - I R, P = V I); collapses to Voc/2
    when the pack cannot deliver that power."""
    if r_ohm <= 0.0 or power_w <= 0.0:
        return open_circuit_v
    disc = open_circuit_v**2 - 4.0 * r_ohm * power_w
    return (open_circuit_v + math.sqrt(max(0.0, disc))) / 2.0


class Battery:
    """Integrates the pack's charge over simulated time."""

    def __init__(self, spec: BatterySpec | Callable[[], BatterySpec]) -> None:
        self._spec = spec if callable(spec) else (lambda: spec)
        self._last_ns: int | None = None
        self.consumed_mah = 0.0
        self.consumed_wh = 0.0

    def step(self, sim_time_ns: int, throttle: float) -> BatteryState:
        """The state after flying at ``throttle`` since the last step."""
        # A 200 Hz path: electrical_power_w and terminal_voltage_v written out, operation for
        # operation (min/max as the builtins choose).
        spec = self._spec()
        last = self._last_ns
        dt_s = 0.0 if last is None else (sim_time_ns - last) / NS_PER_S
        self._last_ns = sim_time_ns
        used = self.consumed_mah / spec.capacity_mah
        used = used if used < 1.0 else 1.0  # min(1.0, used), as the builtin
        cell_v = spec.v_charged_cell - (spec.v_charged_cell - spec.v_empty_cell) * used
        v_oc = spec.cells * cell_v
        if _isfinite(throttle):
            t = throttle if throttle > 0.0 else 0.0
            t = t if t < 1.0 else 1.0
        else:
            t = 0.0
        power_w = AVIONICS_POWER_W + MOTOR_MAX_POWER_W * t**3 / DRIVE_EFFICIENCY
        r_ohm = spec.r_internal_ohm
        if r_ohm <= 0.0 or power_w <= 0.0:
            voltage_v = v_oc
        else:
            disc = v_oc**2 - 4.0 * r_ohm * power_w
            voltage_v = (v_oc + _sqrt(disc if disc > 0.0 else 0.0)) / 2.0
        current_a = power_w / voltage_v if voltage_v > 0 else 0.0
        if dt_s > 0:
            self.consumed_mah += current_a * dt_s / 3.6  # A s -> mAh
            self.consumed_wh += power_w * dt_s / 3600.0
        remaining = 1.0 - self.consumed_mah / spec.capacity_mah
        return battery_state(  # positional, in BatteryState's field order (a 200 Hz path)
            voltage_v,
            current_a,
            self.consumed_mah,
            self.consumed_wh,
            remaining if remaining > 0.0 else 0.0,  # max(0.0, remaining), as the builtin
        )


# Warning levels, as MAV_BATTERY_CHARGE_STATE: OK 1, LOW 2, CRITICAL 3, EMERGENCY 4.
LEVEL_OK, LEVEL_LOW, LEVEL_CRITICAL, LEVEL_EMERGENCY = 1, 2, 3, 4
ACTION_NONE, ACTION_RETURN, ACTION_LAND = "none", "return", "land"


def warning_level(remaining: float, low: float, critical: float, emergency: float) -> int:
    """PX4's battery warning for the fraction ``remaining`` (BAT_LOW_THR, BAT_CRIT_THR,
    BAT_EMERGEN_THR)."""
    if remaining <= emergency:
        return LEVEL_EMERGENCY
    if remaining <= critical:
        return LEVEL_CRITICAL
    if remaining <= low:
        return LEVEL_LOW
    return LEVEL_OK


def failsafe_action(level: int, com_low_bat_act: int) -> str:
    """What PX4's COM_LOW_BAT_ACT does at ``level``: 0 warn only; 1 return at critical (older
    PX4); 2 land at critical; 3 return at critical, land at emergency."""
    if com_low_bat_act == 1 and level >= LEVEL_CRITICAL:
        return ACTION_RETURN
    if com_low_bat_act == 2 and level >= LEVEL_CRITICAL:
        return ACTION_LAND
    if com_low_bat_act == 3:
        if level >= LEVEL_EMERGENCY:
            return ACTION_LAND
        if level >= LEVEL_CRITICAL:
            return ACTION_RETURN
    return ACTION_NONE
