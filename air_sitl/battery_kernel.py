""":meth:`air_sitl.battery.Battery.step` compiled (:mod:`air_sitl.compiled`, group ``flight``):
``electrical_power_w`` and ``terminal_voltage_v`` of :mod:`air_sitl.battery` written out,
operation for operation (the same bytes). ``x ** 2`` and ``t ** 3`` are CPython's, libm's
``pow``, with the exponents read from the pack's array so that the compiler cannot turn them
into products (which round differently).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Array = npt.NDArray[np.float64]
MOTOR_MAX_POWER_W = 600.0  # shaft power at full throttle (a 2-3 kg fixed wing)
AVIONICS_POWER_W = 6.0  # autopilot, GNSS, radio, camera
DRIVE_EFFICIENCY = 0.8  # ESC and motor

# The pack's array: BatterySpec's figures, then the exponents 2.0 and 3.0.
CAPACITY, CELLS, V_CHARGED, V_EMPTY, R_INTERNAL, TWO, THREE = range(7)


@compiled("UniTuple(f8, 5)(f8[::1], f8, f8, f8, f8)")
def step(
    P: Array, consumed_mah: float, consumed_wh: float, dt_s: float, throttle: float
) -> tuple[float, float, float, float, float]:
    """(voltage V, current A, consumed mAh, consumed Wh, remaining) after flying at
    ``throttle`` for ``dt_s`` with the pack ``P``."""
    used = consumed_mah / P[CAPACITY]
    used = used if used < 1.0 else 1.0  # min(1.0, used), as the builtin
    cell_v = P[V_CHARGED] - (P[V_CHARGED] - P[V_EMPTY]) * used
    v_oc = P[CELLS] * cell_v
    if math.isfinite(throttle):
        t = throttle if throttle > 0.0 else 0.0
        t = t if t < 1.0 else 1.0
    else:
        t = 0.0
    power_w = AVIONICS_POWER_W + MOTOR_MAX_POWER_W * t ** P[THREE] / DRIVE_EFFICIENCY
    r_ohm = P[R_INTERNAL]
    if r_ohm <= 0.0 or power_w <= 0.0:
        voltage_v = v_oc
    else:
        disc = v_oc ** P[TWO] - 4.0 * r_ohm * power_w
        voltage_v = (v_oc + math.sqrt(disc if disc > 0.0 else 0.0)) / 2.0
    current_a = power_w / voltage_v if voltage_v > 0 else 0.0
    if dt_s > 0:
        consumed_mah += current_a * dt_s / 3.6  # A s -> mAh
        consumed_wh += power_w * dt_s / 3600.0
    remaining = 1.0 - consumed_mah / P[CAPACITY]
    remaining = remaining if remaining > 0.0 else 0.0  # max(0.0, remaining), as the builtin
    return voltage_v, current_a, consumed_mah, consumed_wh, remaining
