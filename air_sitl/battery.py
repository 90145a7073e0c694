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

import numpy as np

from air_sitl import battery_kernel as bk
from air_sitl.state import BatteryState, battery_state

NS_PER_S = 1_000_000_000
MOTOR_MAX_POWER_W = bk.MOTOR_MAX_POWER_W
AVIONICS_POWER_W = bk.AVIONICS_POWER_W
DRIVE_EFFICIENCY = bk.DRIVE_EFFICIENCY


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
    """Integrates the pack's charge over simulated time.

    ``spec``: the pack, or a function giving it now; :meth:`following` a parameter store
    (the pack read again only when the store changes).
    """

    def __init__(self, spec: BatterySpec | Callable[[], BatterySpec]) -> None:
        self._spec = spec if callable(spec) else (lambda: spec)
        self._last_ns: int | None = None
        self.consumed_mah = 0.0
        self.consumed_wh = 0.0
        self._packed_spec: BatterySpec | None = None
        self._pack = np.zeros(0)
        self._params: VersionedParams | None = None
        self._params_version = -1

    @classmethod
    def following(cls, params: VersionedParams) -> Battery:
        """The pack of ``params`` (BAT1_*, :func:`live_spec`), asked for only after a change
        of the store (its ``version``), not at every step."""
        battery = cls(live_spec(params))
        battery._params = params
        return battery

    def step(self, sim_time_ns: int, throttle: float) -> BatteryState:
        """The state after flying at ``throttle`` since the last step (compiled: a 200 Hz
        path, :mod:`air_sitl.battery_kernel`)."""
        params = self._params
        if params is None or params.version != self._params_version:
            self._refresh_pack()
        last = self._last_ns
        dt_s = 0.0 if last is None else (sim_time_ns - last) / NS_PER_S
        self._last_ns = sim_time_ns
        out = bk.step(self._pack, self.consumed_mah, self.consumed_wh, dt_s, throttle)
        self.consumed_mah = out[2]
        self.consumed_wh = out[3]
        return battery_state(*out)  # BatteryState's field order

    def _refresh_pack(self) -> None:
        """The kernel's array of the pack as ``spec`` gives it now (built again when it
        changes); the store's version it was read at (a battery following one)."""
        if self._params is not None:
            self._params_version = self._params.version
        spec = self._spec()
        if spec is not self._packed_spec:
            self._packed_spec = spec
            self._pack = np.array(
                [spec.capacity_mah, spec.cells, spec.v_charged_cell, spec.v_empty_cell,
                 spec.r_internal_ohm, 2.0, 3.0], dtype=np.float64,
            )  # fmt: skip


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
