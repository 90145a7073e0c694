"""The flight loop's compiled kernels (group ``flight``) round as the Python they replaced.

Squares and cubes are CPython's ``x ** 2`` (libm's ``pow``), not ``x * x``: the two differ
in about one case in a thousand, and a compiler turns ``pow(x, 2.0)`` with a constant
exponent into the product. The flights' bytes (``test_flight_golden``) would show such a
change only where a flight meets those cases; these check the cases themselves.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable

from air_sitl.autopilot import control_kernel
from air_sitl.autopilot.control import ControlGains
from air_sitl.battery import Battery, BatterySpec, electrical_power_w, terminal_voltage_v


def _draws_where_pow_is_not_the_product(
    exponent: int, lo: float, hi: float, base: Callable[[float], float]
) -> list[float]:
    """Draws ``x`` in [lo, hi] whose ``base(x) ** exponent`` is not the product."""
    rng = random.Random(1)
    out = []
    for x in (rng.uniform(lo, hi) for _ in range(20_000)):
        b = base(x)
        if b**exponent != (b * b if exponent == 2 else b * b * b):
            out.append(x)
    assert len(out) > 5  # the cases exist
    return out[:50]


def test_the_gain_schedule_squares_as_cpython() -> None:
    gains = ControlGains()
    g = control_kernel.gains_array(gains, 0.005)
    ref = gains.ref_airspeed_m_s
    for airspeed in _draws_where_pow_is_not_the_product(2, 9.0, 27.0, lambda v: ref / v):
        square = (ref / airspeed) ** 2
        expected = 0.3 if square < 0.3 else 3.0 if square > 3.0 else square
        assert control_kernel.schedule(g, airspeed) == expected


def test_the_battery_cubes_the_throttle_as_cpython() -> None:
    spec = BatterySpec()
    v_full = spec.cells * spec.v_charged_cell
    for throttle in _draws_where_pow_is_not_the_product(3, 0.0, 1.0, lambda t: t):
        power_w = electrical_power_w(throttle)
        state = Battery(spec).step(0, throttle)
        voltage_v = terminal_voltage_v(v_full, spec.r_internal_ohm, power_w)
        assert state.voltage_v == voltage_v
        assert state.current_a == power_w / voltage_v


def test_the_filters_geodetic_conversions_round_as_frames() -> None:
    """nav.geodetic (compiled) gives the bits of frames' Python: the latitude iteration at
    every latitude (the near-pole branch too) and the Euler angles of any attitude."""
    from air_sitl.frames import geodetic2ecef, geodetic_lat_alt, quat2euler
    from air_sitl.nav import geodetic

    rng = random.Random(3)
    for _ in range(20_000):
        lat, lon = rng.uniform(-90.0, 90.0), rng.uniform(-180.0, 180.0)
        x, y, z = geodetic2ecef(lat, lon, rng.uniform(-500.0, 20_000.0))
        p = math.hypot(x, y)
        assert geodetic.lat_alt(p, z) == geodetic_lat_alt(p, z)
    quats = [(1.0, 0.0, 0.0, 0.0), (math.sqrt(0.5), 0.0, math.sqrt(0.5), 0.0)]
    for _ in range(20_000):
        q = [rng.gauss(0.0, 1.0) for _ in range(4)]
        norm = math.sqrt(sum(v * v for v in q))
        quats.append((q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm))
    for w, x, y, z in quats:
        assert geodetic.euler(w, x, y, z) == quat2euler((w, x, y, z))
