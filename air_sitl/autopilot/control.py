"""Inner-loop control: attitude, total-energy speed/height, take-off and landing laws.

Turns a :class:`ControlTarget` (what guidance wants: bank, altitude, airspeed, phase) into an
:class:`ActuatorCommand` once per physics step. Pure Python math on plain floats, so a flight
is cheap and bit-for-bit repeatable.

Loops (all gains in :class:`ControlGains`):

- roll: bank error -> aileron, roll-rate damping, small integrator (prop torque, asymmetry);
- pitch: pitch error -> elevator, pitch-rate damping with the turn's steady pitch rate fed
  forward, integrator that becomes the elevator trim;
- yaw: rudder cancels the lateral specific force (sideslip) and damps yaw rate about the
  coordinated turn rate; on the ground the rudder (and nose wheel) steers to the heading;
- TECS: throttle closes the total specific-energy rate (flight-path angle plus
  acceleration / g), pitch the energy balance (flight-path angle minus acceleration / g),
  both with anti-windup integrators, climb/sink rate and pitch limits.

Phases: IDLE (brakes, nothing else), GROUND_ROLL (full throttle, nose wheel and rudder hold
the heading, nose-down elevator until the rotation speed, then the rotation attitude),
CLIMB (climb throttle, pitch for airspeed, throttle trimmed back above the climb-rate limit),
CRUISE (TECS + bank tracking), LAND (idle, pitch for the approach speed, flare below
``flare_height_m`` on a sink rate proportional to height; on the ground: brakes, steer).

Surface gains are scheduled with dynamic pressure: effectiveness goes as airspeed squared.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from air_sitl.autopilot import control_kernel as ck
from air_sitl.autopilot.target import ControlPhase, ControlTarget
from air_sitl.clock import NS_PER_S, PHYSICS_STEP_NS
from air_sitl.state import ActuatorCommand, VehicleState, actuator_command

GRAVITY_M_S2 = ck.GRAVITY_M_S2
_CRUISE = ControlPhase.CRUISE


@dataclass(frozen=True, slots=True, kw_only=True)
class ControlGains:
    """Gains, limits and reference figures of one airframe (defaults: airsitl_uav)."""

    # Reference (trim) point: surface gains are tuned here and scaled with (ref / V)^2.
    ref_airspeed_m_s: float = 15.0
    trim_throttle: float = 0.63
    trim_elevator: float = 0.01
    trim_pitch_rad: float = 0.022
    min_airspeed_m_s: float = 11.0  # scheduling and speed-demand floor (above stall)
    max_airspeed_m_s: float = 24.0
    # Roll
    roll_kp: float = 1.0  # aileron per rad of bank error
    roll_ki: float = 0.2  # aileron per rad*s
    roll_kd: float = 0.08  # aileron per rad/s of roll rate
    roll_i_limit: float = 0.2
    max_bank_rad: float = math.radians(45.0)
    # Pitch
    pitch_kp: float = 1.2  # elevator per rad of pitch error (elevator + = nose down)
    pitch_ki: float = 0.8
    pitch_kd: float = 0.25  # elevator per rad/s of pitch rate
    pitch_i_limit: float = 0.6
    max_pitch_rad: float = math.radians(25.0)
    min_pitch_rad: float = math.radians(-20.0)
    # Yaw
    yaw_ky: float = 0.05  # rudder per m/s^2 of lateral specific force
    yaw_kr: float = 0.3  # rudder per rad/s of yaw-rate error
    # TECS (energy rates in rad: flight-path angle plus or minus acceleration / g)
    height_k: float = 0.25  # demanded climb rate per m of height error, 1/s
    speed_k: float = 0.3  # demanded acceleration per m/s of speed error, 1/s
    max_accel_m_s2: float = 1.5
    max_vert_accel_m_s2: float = 1.0  # slew limit of the demanded climb rate
    demand_filter_s: float = 1.0  # time constant of the altitude-demand rate feed-forward
    accel_filter_s: float = 0.5  # time constant of the along-path acceleration estimate
    throttle_ff: float = 1.0  # throttle per rad of demanded energy rate
    throttle_kp: float = 1.2
    throttle_ki: float = 0.3
    balance_kp: float = 1.0  # pitch (rad) per rad of energy-balance error
    balance_ki: float = 0.25
    energy_i_limit: float = 0.5
    # Take-off and climb-out
    rotate_airspeed_m_s: float = 11.0
    roll_elevator: float = 0.3  # elevator held during the take-off run, before rotation
    rotate_pitch_rad: float = math.radians(8.0)
    climb_throttle: float = 1.0
    climb_pitch_rad: float = math.radians(12.0)  # nominal climb attitude, trimmed for speed
    climb_speed_k: float = 0.05  # rad of pitch per m/s of speed excess
    steer_k: float = 3.0  # rudder / nose wheel per rad of heading error on the ground
    steer_kr: float = 0.5
    # Landing
    flare_height_m: float = 3.0
    flare_sink_m_s: float = 0.3
    flare_k: float = 0.5  # demanded sink rate per m of height (1/s) during the flare
    touchdown_pitch_rad: float = math.radians(4.0)


# Light aircraft from the jsbsim package: one rough set (not tuned) with their own speeds.
_LIGHT_AIRCRAFT = ControlGains(
    trim_throttle=0.65,
    trim_elevator=0.0,
    trim_pitch_rad=0.0,
    roll_kp=1.2,
    roll_kd=0.3,
    pitch_kp=2.0,
    pitch_kd=0.8,
    yaw_ky=0.02,
    height_k=0.15,
    speed_k=0.2,
    throttle_ff=1.5,
    rotate_pitch_rad=math.radians(6.0),
    climb_pitch_rad=math.radians(8.0),
    climb_speed_k=0.03,
    steer_k=0.5,
)
_GAINS = {
    "c172p": dataclasses.replace(
        _LIGHT_AIRCRAFT,
        ref_airspeed_m_s=50.0,
        min_airspeed_m_s=30.0,
        max_airspeed_m_s=60.0,
        rotate_airspeed_m_s=28.0,
        flare_height_m=5.0,
    ),
    "J3Cub": dataclasses.replace(
        _LIGHT_AIRCRAFT,
        ref_airspeed_m_s=35.0,
        trim_throttle=0.6,
        min_airspeed_m_s=22.0,
        max_airspeed_m_s=45.0,
        rotate_airspeed_m_s=20.0,
        flare_height_m=4.0,
    ),
}


def gains_for(aircraft: str) -> ControlGains:
    """Default gains for a known aircraft; the airsitl_uav set for any other."""
    return _GAINS.get(aircraft, ControlGains())


def _clamp(x: float, lo: float, hi: float) -> float:
    return lo if x < lo else hi if x > hi else x


def _wrap_pi(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class Controller:
    """The control laws of every phase; state is a handful of floats (integrators, filters)
    in one array that the compiled laws (:mod:`~air_sitl.autopilot.control_kernel`) update.

    ``trim`` (for example :attr:`JSBSimModel.trim_command` after an air start) seeds the
    elevator and throttle integrators so a trimmed start stays steady from the first step.
    """

    def __init__(
        self,
        gains: ControlGains | None = None,
        *,
        dt_s: float = PHYSICS_STEP_NS / NS_PER_S,
        trim: ActuatorCommand | None = None,
    ) -> None:
        self.gains = gains if gains is not None else ControlGains()
        self.dt_s = dt_s
        self._g = ck.gains_array(self.gains, dt_s)
        self._m = np.zeros(ck.MEMORY)
        self._m[ck.PITCH_LO] = self.gains.min_pitch_rad
        self._m[ck.PITCH_HI] = self.gains.max_pitch_rad
        self.reset(trim)  # the integrators and filters

    def reset(self, trim: ActuatorCommand | None = None) -> None:
        """Clear the integrators and filters; seed them from ``trim`` (an air start) if given."""
        m = self._m
        m[ck.ROLL_I] = 0.0
        m[ck.PITCH_I] = self.gains.trim_elevator
        m[ck.THROTTLE_I] = 0.0
        m[ck.BALANCE_I] = 0.0
        m[ck.VDOT] = 0.0
        m[ck.HDOT_DEM] = 0.0
        m[ck.H_DEM_PREV] = math.nan
        m[ck.H_DEM_RATE] = 0.0
        # An air start (trim given) is already cruising; otherwise the aircraft is parked.
        self._prev_phase: ControlPhase = (
            ControlPhase.CRUISE if trim is not None else ControlPhase.IDLE
        )
        if trim is not None:
            m[ck.PITCH_I] = trim.elevator
            m[ck.THROTTLE_I] = trim.throttle - self.gains.trim_throttle

    # ------------------------------------------------------------------ entry point

    def update(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        """One step of the control law of ``target.phase``."""
        phase = target.phase
        if phase is _CRUISE and self._prev_phase is _CRUISE:
            # The 200 Hz path: _cruise written out, one compiled call.
            return actuator_command(  # positional, in ActuatorCommand's field order
                *ck.cruise(
                    self._g, self._m, state.roll_rad, state.pitch_rad, state.rate_frd_rad_s,
                    state.vel_ned_m_s[2], state.specific_force_frd_m_s2, state.airspeed_m_s,
                    state.alt_amsl_m, state.on_ground, target.roll_rad,
                    target.altitude_amsl_m, target.airspeed_m_s, target.climb_rate_limit_m_s,
                    target.pitch_min_rad, target.pitch_max_rad,
                )
            )  # fmt: skip
        g = self.gains
        m = self._m
        # max() and min() written out, choosing as the builtins do.
        lo, hi = target.pitch_min_rad, target.pitch_max_rad
        m[ck.PITCH_LO] = lo if lo > g.min_pitch_rad else g.min_pitch_rad
        m[ck.PITCH_HI] = hi if hi < g.max_pitch_rad else g.max_pitch_rad
        if phase is ControlPhase.IDLE:
            self.reset()  # parked: nothing to remember
            return ActuatorCommand(brake=1.0)
        if phase is not self._prev_phase:
            # Entering a phase: its pitch offset integrator means something else there, and
            # the climb-rate demand starts from what the aircraft is doing.
            m[ck.BALANCE_I] = 0.0
            m[ck.HDOT_DEM] = -state.vel_ned_m_s[2]
            m[ck.H_DEM_PREV] = math.nan
        if phase is ControlPhase.GROUND_ROLL:
            cmd = self._ground_roll(state, target)
        elif phase is ControlPhase.CLIMB:
            cmd = self._climb(state, target)
        elif phase is ControlPhase.CRUISE:
            cmd = self._cruise(state, target)
        else:
            cmd = self._land(state, target)
        self._prev_phase = phase
        return cmd

    # ------------------------------------------------------------------ inner loops

    def _schedule(self, airspeed_m_s: float) -> float:
        """Surface-gain factor: (V_ref / V)^2, bounded for very slow and very fast flight."""
        return float(ck.schedule(self._g, airspeed_m_s))

    def _integrate(self, value: float, rate: float, limit: float) -> float:
        """One step of an integrator, kept within [-limit, limit]."""
        return _clamp(value + rate * self.dt_s, -limit, limit)

    def _aileron(self, state: VehicleState, bank_cmd_rad: float, scale: float) -> float:
        return float(
            ck.aileron(
                self._g, self._m, state.roll_rad, state.rate_frd_rad_s[0], state.on_ground,
                bank_cmd_rad, scale,
            )
        )  # fmt: skip

    def _elevator(self, state: VehicleState, pitch_cmd_rad: float, scale: float) -> float:
        return float(
            ck.elevator(
                self._g, self._m, state.pitch_rad, state.rate_frd_rad_s[1], state.roll_rad,
                state.airspeed_m_s, pitch_cmd_rad, scale,
            )
        )  # fmt: skip

    def _rudder_air(self, state: VehicleState, scale: float) -> float:
        """``scale``: :meth:`_schedule` of the state's airspeed."""
        return float(
            ck.rudder_air(
                self._g, state.roll_rad, state.pitch_rad, state.airspeed_m_s,
                state.specific_force_frd_m_s2[1], state.rate_frd_rad_s[2], scale,
            )
        )  # fmt: skip

    def _steer(self, state: VehicleState, heading_rad: float) -> float:
        g = self.gains
        err = _wrap_pi(heading_rad - state.yaw_rad)
        # Nose-wheel yaw rate grows with ground speed: soften the gain as the roll speeds up.
        v_n, v_e, _ = state.vel_ned_m_s
        soften = _clamp(8.0 / max(math.hypot(v_n, v_e), 1e-3), 0.3, 1.0)
        return _clamp((g.steer_k * err - g.steer_kr * state.rate_frd_rad_s[2]) * soften, -1.0, 1.0)

    # ------------------------------------------------------------------ phases

    def _ground_roll(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        g = self.gains
        scale = self._schedule(state.airspeed_m_s)
        aileron = self._aileron(state, 0.0, scale)
        if state.airspeed_m_s >= g.rotate_airspeed_m_s or not state.on_ground:
            elevator = self._elevator(state, g.rotate_pitch_rad, scale)
        else:
            self._m[ck.PITCH_I] = g.trim_elevator
            # Nose-down elevator keeps weight on the steerable nose wheel until rotation speed.
            elevator = g.roll_elevator
        rudder = self._steer(state, target.heading_rad)
        if not state.on_ground:
            rudder = self._rudder_air(state, scale)
        return ActuatorCommand(
            aileron=aileron, elevator=elevator, rudder=rudder, throttle=g.climb_throttle
        )

    def _climb(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        p, q, r = state.rate_frd_rad_s
        return actuator_command(  # positional, in ActuatorCommand's field order
            *ck.climb(
                self._g, self._m, state.roll_rad, state.pitch_rad, p, q, r,
                state.vel_ned_m_s[2], state.specific_force_frd_m_s2[1], state.airspeed_m_s,
                state.on_ground, target.roll_rad, target.airspeed_m_s,
                target.climb_rate_limit_m_s,
            )
        )  # fmt: skip

    def _cruise(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        return actuator_command(  # positional, in ActuatorCommand's field order
            *ck.cruise(
                self._g, self._m, state.roll_rad, state.pitch_rad, state.rate_frd_rad_s,
                state.vel_ned_m_s[2], state.specific_force_frd_m_s2, state.airspeed_m_s,
                state.alt_amsl_m, state.on_ground, target.roll_rad, target.altitude_amsl_m,
                target.airspeed_m_s, target.climb_rate_limit_m_s, target.pitch_min_rad,
                target.pitch_max_rad,
            )
        )  # fmt: skip

    def _land(self, state: VehicleState, target: ControlTarget) -> ActuatorCommand:
        g = self.gains
        scale = self._schedule(state.airspeed_m_s)
        if state.on_ground:
            # Roll-out: nose down onto the wheel, brakes, steer the heading, wings level.
            self._m[ck.PITCH_I] = g.trim_elevator
            return ActuatorCommand(
                aileron=self._aileron(state, 0.0, scale),
                elevator=0.3,
                rudder=self._steer(state, target.heading_rad),
                throttle=0.0,
                brake=1.0 if state.airspeed_m_s < g.rotate_airspeed_m_s else 0.3,
            )
        height = state.alt_amsl_m - target.ground_amsl_m
        if height > g.flare_height_m:
            # Glide: pitch for the approach airspeed, throttle idle.
            speed_dem = _clamp(target.airspeed_m_s, g.min_airspeed_m_s, g.max_airspeed_m_s)
            speed_err = state.airspeed_m_s - speed_dem
            balance_i = self._integrate(float(self._m[ck.BALANCE_I]), 0.01 * speed_err, 0.2)
            self._m[ck.BALANCE_I] = balance_i
            pitch_cmd = g.trim_pitch_rad - 0.06 + 0.05 * speed_err + balance_i
            bank = target.roll_rad
        else:
            # Flare: sink rate proportional to height, pitch up to hold it; wings level.
            sink_dem = max(g.flare_sink_m_s, g.flare_k * height)
            sink = state.vel_ned_m_s[2]
            pitch_cmd = state.pitch_rad + 0.1 * (sink - sink_dem)
            pitch_cmd = _clamp(pitch_cmd, -0.05, g.max_pitch_rad * 0.6)
            bank = 0.0
        return ActuatorCommand(
            aileron=self._aileron(state, bank, scale),
            elevator=self._elevator(state, pitch_cmd, scale),
            rudder=self._rudder_air(state, scale),
            throttle=0.0,
        )
