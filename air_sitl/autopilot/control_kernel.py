"""The controller's 200 Hz laws compiled (:mod:`air_sitl.compiled`, group ``flight``): the
attitude loops and the total-energy law of :class:`air_sitl.autopilot.control.Controller`,
the cruise phase in one call.

The gains come in a float64 array (:func:`gains_array`, indices below), the controller's
integrators and filters in another (``M``, indices below) that the kernels update in place.
Operation for operation as the Python laws were (the same bytes): ``x ** 2`` is CPython's,
libm's ``pow(x, 2.0)``, with the exponent read from the gains array (``G[TWO]``) so that the
compiler cannot turn it into ``x * x`` (which rounds differently in about 1 case in 1,000).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Array = npt.NDArray[np.float64]
GRAVITY_M_S2 = 9.80665

# The gains array: ControlGains' fields of these names, then the step and the exponent 2.0,
# then the climb's (CLIMB_FIELDS).
GAIN_FIELDS = (
    "ref_airspeed_m_s", "min_airspeed_m_s", "max_airspeed_m_s", "trim_throttle",
    "trim_pitch_rad", "roll_kp", "roll_ki", "roll_kd", "roll_i_limit", "max_bank_rad",
    "pitch_kp", "pitch_ki", "pitch_kd", "pitch_i_limit", "max_pitch_rad", "min_pitch_rad",
    "yaw_ky", "yaw_kr", "height_k", "speed_k", "max_accel_m_s2", "max_vert_accel_m_s2",
    "demand_filter_s", "accel_filter_s", "throttle_ff", "throttle_kp", "throttle_ki",
    "balance_kp", "balance_ki", "energy_i_limit",
)  # fmt: skip
(REF_V, MIN_V, MAX_V, TRIM_THROTTLE, TRIM_PITCH, ROLL_KP, ROLL_KI, ROLL_KD, ROLL_I_LIMIT,
 MAX_BANK, PITCH_KP, PITCH_KI, PITCH_KD, PITCH_I_LIMIT, MAX_PITCH, MIN_PITCH, YAW_KY, YAW_KR,
 HEIGHT_K, SPEED_K, MAX_ACCEL, MAX_VERT_ACCEL, DEMAND_FILTER_S, ACCEL_FILTER_S, THROTTLE_FF,
 THROTTLE_KP, THROTTLE_KI, BALANCE_KP, BALANCE_KI, ENERGY_I_LIMIT, DT, TWO, CLIMB_PITCH,
 CLIMB_SPEED_K, CLIMB_THROTTLE) = range(35)  # fmt: skip
CLIMB_FIELDS = ("climb_pitch_rad", "climb_speed_k", "climb_throttle")
# The memory array: integrators, filters, the pitch limits of the current step.
(ROLL_I, PITCH_I, THROTTLE_I, BALANCE_I, VDOT, HDOT_DEM, H_DEM_PREV, H_DEM_RATE, PITCH_LO,
 PITCH_HI) = range(10)  # fmt: skip
MEMORY = 10


def gains_array(gains: Any, dt_s: float) -> Array:
    """``gains`` (a ControlGains) as the kernels' array."""
    return np.array(
        [*(float(getattr(gains, name)) for name in GAIN_FIELDS), dt_s, 2.0,
         *(float(getattr(gains, name)) for name in CLIMB_FIELDS)]
    )  # fmt: skip


@compiled("f8(f8[::1], f8)")
def schedule(G: Array, airspeed_m_s: float) -> float:
    """Surface-gain factor: (V_ref / V)^2, bounded for very slow and very fast flight."""
    slowest = 0.5 * G[MIN_V]
    v = airspeed_m_s if airspeed_m_s > slowest else slowest
    k = (G[REF_V] / v) ** G[TWO]
    return 0.3 if k < 0.3 else 3.0 if k > 3.0 else k


@compiled("f8(f8[::1], f8[::1], f8, f8, b1, f8, f8)")
def aileron(
    G: Array, M: Array, roll: float, p: float, on_ground: bool, bank_cmd_rad: float, scale: float
) -> float:
    """Bank error -> aileron, roll-rate damping, integrator (``M[ROLL_I]``)."""
    hi = G[MAX_BANK]
    lo = -hi
    bank = lo if bank_cmd_rad < lo else hi if bank_cmd_rad > hi else bank_cmd_rad
    err = bank - roll
    raw = G[ROLL_KP] * err + M[ROLL_I] - G[ROLL_KD] * p
    x = scale * raw
    out = -1.0 if x < -1.0 else 1.0 if x > 1.0 else x
    # Anti-windup: integrate only in the air and while the output is not pushed further
    # into its limit.
    if not (on_ground or (out >= 1.0 and err > 0.0) or (out <= -1.0 and err < 0.0)):
        i = M[ROLL_I] + (G[ROLL_KI] * err) * G[DT]
        limit = G[ROLL_I_LIMIT]
        M[ROLL_I] = -limit if i < -limit else limit if i > limit else i
    return out


@compiled("f8(f8[::1], f8[::1], f8, f8, f8, f8, f8, f8)")
def elevator(
    G: Array, M: Array, pitch: float, q: float, roll: float, airspeed_m_s: float,
    pitch_cmd_rad: float, scale: float,
) -> float:  # fmt: skip
    """Pitch error -> elevator, pitch-rate damping about a level turn's, integrator (the
    elevator trim, ``M[PITCH_I]``) within ``M[PITCH_LO]``..``M[PITCH_HI]``."""
    lo, hi = M[PITCH_LO], M[PITCH_HI]
    pitch_cmd = lo if pitch_cmd_rad < lo else hi if pitch_cmd_rad > hi else pitch_cmd_rad
    err = pitch_cmd - pitch
    # Steady pitch rate of a level turn: g/V * sin^2(phi) / cos(phi).
    v = airspeed_m_s
    v = G[MIN_V] if G[MIN_V] > v else v
    cos_phi = math.cos(roll)
    cos_phi = 0.3 if cos_phi < 0.3 else cos_phi
    q_ff = GRAVITY_M_S2 / v * math.sin(roll) ** G[TWO] / cos_phi
    fb = -G[PITCH_KP] * err + G[PITCH_KD] * (q - q_ff)
    x = M[PITCH_I] + scale * fb
    out = -1.0 if x < -1.0 else 1.0 if x > 1.0 else x
    # The integrator is the elevator trim; elevator + = nose down, hence the minus signs.
    push = -err
    if not ((out >= 1.0 and push > 0.0) or (out <= -1.0 and push < 0.0)):
        i = M[PITCH_I] + (-(scale * G[PITCH_KI] * err)) * G[DT]
        limit = G[PITCH_I_LIMIT]
        M[PITCH_I] = -limit if i < -limit else limit if i > limit else i
    return out


@compiled("f8(f8[::1], f8, f8, f8, f8, f8, f8)")
def rudder_air(
    G: Array, roll: float, pitch: float, airspeed_m_s: float, ay: float, r: float, scale: float
) -> float:
    """Rudder cancelling the lateral specific force and damping yaw rate about the
    coordinated turn's; ``scale``: :func:`schedule` of the airspeed."""
    v = airspeed_m_s
    v = G[MIN_V] if G[MIN_V] > v else v
    r_turn = GRAVITY_M_S2 / v * math.sin(roll) * math.cos(pitch)
    out = (-G[YAW_KY] * ay - G[YAW_KR] * (r - r_turn)) * scale
    return -1.0 if out < -1.0 else 1.0 if out > 1.0 else out


@compiled
def _tecs(
    G: Array, M: Array, pitch: float, roll: float, vd: float, fx: float, airspeed: float,
    h: float, height_dem_m: float, speed_dem_m_s: float, climb_limit: float,
) -> tuple[float, float]:  # fmt: skip
    """Pitch command (rad) and throttle from the total-energy laws."""
    dt = G[DT]
    v_min, v_max = G[MIN_V], G[MAX_V]
    v = v_min if v_min > airspeed else airspeed
    speed_dem = (
        v_min if speed_dem_m_s < v_min else v_max if speed_dem_m_s > v_max else speed_dem_m_s
    )
    climb_max = 0.1 if climb_limit < 0.1 else climb_limit
    sink_max = -climb_max
    hdot = -vd
    # Feed forward how fast the demanded altitude moves (a glide slope, a ramped climb),
    # low-pass filtered: guidance updates its target only every few steps.
    if M[H_DEM_PREV] == M[H_DEM_PREV]:  # not NaN: a previous demand exists
        rate = (height_dem_m - M[H_DEM_PREV]) / dt
        rate = sink_max if rate < sink_max else climb_max if rate > climb_max else rate
        k = dt / G[DEMAND_FILTER_S]
        M[H_DEM_RATE] += (rate - M[H_DEM_RATE]) * (1.0 if k > 1.0 else k)
    M[H_DEM_PREV] = height_dem_m
    x = M[H_DEM_RATE] + G[HEIGHT_K] * (height_dem_m - h)
    hdot_dem = sink_max if x < sink_max else climb_max if x > climb_max else x
    # Slew the demanded climb rate: a step in altitude gives a smooth pull-up.
    slew = G[MAX_VERT_ACCEL] * dt
    lo, hi = M[HDOT_DEM] - slew, M[HDOT_DEM] + slew
    hdot_dem = lo if hdot_dem < lo else hi if hdot_dem > hi else hdot_dem
    M[HDOT_DEM] = hdot_dem
    acc_max = G[MAX_ACCEL]
    x = G[SPEED_K] * (speed_dem - airspeed)
    vdot_dem = -acc_max if x < -acc_max else acc_max if x > acc_max else x
    # Along-path acceleration from the accelerometer: u_dot = f_x - g sin(theta), low-pass
    # filtered: thrust shows in f_x at once, and unfiltered it closes a fast loop through
    # the throttle that rings at the step rate.
    vdot_raw = fx - GRAVITY_M_S2 * math.sin(pitch)
    k = dt / G[ACCEL_FILTER_S]
    M[VDOT] += (vdot_raw - M[VDOT]) * (1.0 if k > 1.0 else k)
    vdot = M[VDOT]
    gamma_dem = hdot_dem / v
    gamma = hdot / v
    acc_dem = vdot_dem / GRAVITY_M_S2
    acc = vdot / GRAVITY_M_S2
    # Total energy rate -> throttle.
    ste_dem = gamma_dem + acc_dem
    ste_err = ste_dem - (gamma + acc)
    # Extra drag in a turn: the lift rises by 1/cos(phi), the induced drag with its square.
    cos_roll = math.cos(roll)
    turn = 1.0 / (0.5 if cos_roll < 0.5 else cos_roll) ** G[TWO] - 1.0
    trim = G[TRIM_THROTTLE]
    thr_ff = trim + G[THROTTLE_FF] * ste_dem + 0.25 * turn * trim
    throttle = thr_ff + G[THROTTLE_KP] * ste_err + M[THROTTLE_I]
    throttle_out = 0.0 if throttle < 0.0 else 1.0 if throttle > 1.0 else throttle
    limit = G[ENERGY_I_LIMIT]
    if not ((throttle >= 1.0 and ste_err > 0.0) or (throttle <= 0.0 and ste_err < 0.0)):
        i = M[THROTTLE_I] + (G[THROTTLE_KI] * ste_err) * dt
        M[THROTTLE_I] = -limit if i < -limit else limit if i > limit else i
    # Energy balance -> pitch.
    seb_err = (gamma_dem - acc_dem) - (gamma - acc)
    pitch_out = G[TRIM_PITCH] + gamma_dem + G[BALANCE_KP] * seb_err + M[BALANCE_I]
    if not (
        (pitch_out >= G[MAX_PITCH] and seb_err > 0.0)
        or (pitch_out <= G[MIN_PITCH] and seb_err < 0.0)
    ):
        i = M[BALANCE_I] + (G[BALANCE_KI] * seb_err) * dt
        M[BALANCE_I] = -limit if i < -limit else limit if i > limit else i
    return pitch_out, throttle_out


@compiled(
    "UniTuple(f8, 5)(f8[::1], f8[::1], f8, f8, UniTuple(f8, 3), f8, UniTuple(f8, 3), f8, f8, "
    "b1, f8, f8, f8, f8, f8, f8)"
)
def cruise(
    G: Array, M: Array, roll: float, pitch: float, rates: tuple[float, float, float],
    vd: float, force: tuple[float, float, float], airspeed: float, h: float, on_ground: bool,
    roll_cmd: float, height_dem_m: float, speed_dem_m_s: float, climb_limit: float,
    pitch_min: float, pitch_max: float,
) -> tuple[float, float, float, float, float]:  # fmt: skip
    """One step of the cruise phase from the state's attitude, rates (p, q, r), down
    velocity, specific force (x, y, z: the VehicleState's tuples as they are), airspeed and
    altitude AMSL and the target's: (aileron, elevator, rudder, throttle, brake),
    ActuatorCommand's fields."""
    p, q, r = rates
    fx, fy, _ = force
    M[PITCH_LO] = pitch_min if pitch_min > G[MIN_PITCH] else G[MIN_PITCH]
    M[PITCH_HI] = pitch_max if pitch_max < G[MAX_PITCH] else G[MAX_PITCH]
    scale = schedule(G, airspeed)
    pitch_cmd, throttle = _tecs(
        G, M, pitch, roll, vd, fx, airspeed, h, height_dem_m, speed_dem_m_s, climb_limit
    )
    return (
        aileron(G, M, roll, p, on_ground, roll_cmd, scale),
        elevator(G, M, pitch, q, roll, airspeed, pitch_cmd, scale),
        rudder_air(G, roll, pitch, airspeed, fy, r, scale),
        throttle,
        0.0,
    )


@compiled("UniTuple(f8, 5)(f8[::1], f8[::1], f8, f8, f8, f8, f8, f8, f8, f8, b1, f8, f8, f8)")
def climb(
    G: Array, M: Array, roll: float, pitch: float, p: float, q: float, r: float, vd: float,
    fy: float, airspeed: float, on_ground: bool, roll_cmd: float, speed_dem_m_s: float,
    climb_limit: float,
) -> tuple[float, float, float, float, float]:  # fmt: skip
    """One step of the climb-out from the state's attitude, rates, down velocity, lateral
    specific force and airspeed and the target's bank, airspeed and climb-rate limit:
    (aileron, elevator, rudder, throttle, brake): pitch for airspeed (too fast, pitch up;
    ``M[BALANCE_I]`` trims it), full power less what would climb faster than the limit."""
    scale = schedule(G, airspeed)
    v_min, v_max = G[MIN_V], G[MAX_V]
    speed_dem = (
        v_min if speed_dem_m_s < v_min else v_max if speed_dem_m_s > v_max else speed_dem_m_s
    )
    speed_err = airspeed - speed_dem
    k = G[CLIMB_SPEED_K]
    limit = G[ENERGY_I_LIMIT]
    i = M[BALANCE_I] + k * 0.2 * speed_err * G[DT]
    balance_i = -limit if i < -limit else limit if i > limit else i
    M[BALANCE_I] = balance_i
    pitch_cmd = G[CLIMB_PITCH] + k * speed_err + balance_i
    trim_pitch = G[TRIM_PITCH]
    pitch_cmd = trim_pitch if trim_pitch > pitch_cmd else pitch_cmd  # max(pitch_cmd, trim)
    elevator_out = elevator(G, M, pitch, q, roll, airspeed, pitch_cmd, scale)
    aileron_out = aileron(G, M, roll, p, on_ground, roll_cmd, scale)
    rudder_out = 0.0 if on_ground else rudder_air(G, roll, pitch, airspeed, fy, r, scale)
    over = -vd - climb_limit
    throttle = G[CLIMB_THROTTLE]
    if over > 0.0:
        v = 1.0 if airspeed < 1.0 else airspeed  # max(airspeed, 1.0)
        x = G[CLIMB_THROTTLE] - 3.0 * G[THROTTLE_FF] * over / v
        trim = G[TRIM_THROTTLE]
        throttle = trim if trim > x else x  # max(x, trim)
    M[THROTTLE_I] = 0.0
    return aileron_out, elevator_out, rudder_out, throttle, 0.0
