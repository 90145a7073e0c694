"""Controller flying the real airsitl_uav in JSBSim: turns, climbs, take-off and landing."""

from __future__ import annotations

import math
from collections.abc import Callable

import pytest

from air_sitl.autopilot.control import ControlGains, Controller, gains_for
from air_sitl.autopilot.target import ControlPhase, ControlTarget
from air_sitl.clock import PHYSICS_STEP_NS
from air_sitl.fdm.base import InitialCondition, Wind
from air_sitl.fdm.jsbsim_model import JSBSimModel
from air_sitl.state import ActuatorCommand, GeoPoint, VehicleState

# Real JSBSim flights (fast: the whole module takes a few seconds).
pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3977, lon_deg=8.5456, alt_amsl_m=488.0)
STEPS_PER_S = 1_000_000_000 // PHYSICS_STEP_NS
CRUISE_ALT_M = HOME.alt_amsl_m + 200.0

TargetFn = Callable[[VehicleState], ControlTarget]


def _air_start(
    model: JSBSimModel,
    wind: Wind | None = None,
    *,
    alt_amsl_m: float = CRUISE_ALT_M,
    heading_rad: float = 0.3,
) -> tuple[VehicleState, Controller]:
    ic = InitialCondition(
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=alt_amsl_m,
        heading_rad=heading_rad,
        airspeed_m_s=15.0,
        on_ground=False,
    )
    state = model.reset(HOME, ic, wind or Wind())
    return state, Controller(trim=model.trim_command)


def _ground_start(model: JSBSimModel, heading_rad: float) -> tuple[VehicleState, Controller]:
    ic = InitialCondition(
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=HOME.alt_amsl_m,
        heading_rad=heading_rad,
    )
    return model.reset(HOME, ic, Wind()), Controller()


def _fly(
    model: JSBSimModel,
    controller: Controller,
    state: VehicleState,
    target: TargetFn,
    seconds: float,
) -> list[VehicleState]:
    out = []
    for _ in range(int(seconds * STEPS_PER_S)):
        state = model.step(controller.update(state, target(state)))
        out.append(state)
    return out


def _cruise(roll_rad: float = 0.0, alt_m: float = CRUISE_ALT_M, speed: float = 15.0) -> TargetFn:
    target = ControlTarget(
        phase=ControlPhase.CRUISE, roll_rad=roll_rad, altitude_amsl_m=alt_m, airspeed_m_s=speed
    )
    return lambda _state: target


def test_cruise_from_a_trimmed_start_stays_steady() -> None:
    model = JSBSimModel()
    state, controller = _air_start(model)
    states = _fly(model, controller, state, _cruise(), 30.0)
    assert max(abs(s.alt_amsl_m - CRUISE_ALT_M) for s in states) < 0.5
    assert max(abs(s.airspeed_m_s - 15.0) for s in states) < 0.3


def test_30_degree_bank_turn_holds_altitude_within_5_m() -> None:
    model = JSBSimModel()
    state, controller = _air_start(model)
    states = _fly(model, controller, state, _cruise(roll_rad=math.radians(30.0)), 60.0)
    assert max(abs(s.alt_amsl_m - CRUISE_ALT_M) for s in states) < 5.0
    settled = states[10 * STEPS_PER_S :]
    assert all(abs(math.degrees(s.roll_rad) - 30.0) < 3.0 for s in settled)
    assert all(abs(s.airspeed_m_s - 15.0) < 1.5 for s in settled)
    # Coordinated: little lateral specific force, turn rate of a level coordinated turn.
    assert all(abs(s.specific_force_frd_m_s2[1]) < 0.6 for s in settled)
    yaw_rate = sum(s.rate_frd_rad_s[2] for s in settled) / len(settled)
    # body yaw rate r = psi_dot cos(phi), psi_dot = g tan(phi) / V
    assert yaw_rate == pytest.approx(9.80665 * math.sin(math.radians(30.0)) / 15.0, rel=0.1)


def test_tecs_climbs_and_descends_to_a_new_altitude_holding_speed() -> None:
    model = JSBSimModel()
    state, controller = _air_start(model)
    up = _fly(model, controller, state, _cruise(alt_m=CRUISE_ALT_M + 30.0), 40.0)
    assert up[-1].alt_amsl_m == pytest.approx(CRUISE_ALT_M + 30.0, abs=1.5)
    climb_rates = [-s.vel_ned_m_s[2] for s in up]
    assert max(climb_rates) < 3.0 + 0.5  # the target's climb-rate limit
    assert min(s.airspeed_m_s for s in up) > 13.0
    down = _fly(model, controller, up[-1], _cruise(alt_m=CRUISE_ALT_M - 20.0), 40.0)
    assert down[-1].alt_amsl_m == pytest.approx(CRUISE_ALT_M - 20.0, abs=1.5)
    assert max(s.airspeed_m_s for s in down) < 17.5


def test_climb_rate_at_full_throttle_is_at_least_2_m_s() -> None:
    model = JSBSimModel()
    state, controller = _air_start(model)
    target = ControlTarget(phase=ControlPhase.CLIMB, airspeed_m_s=15.0, climb_rate_limit_m_s=20.0)
    states = _fly(model, controller, state, lambda _s: target, 30.0)
    steady = states[15 * STEPS_PER_S :]
    climb = (steady[-1].alt_amsl_m - steady[0].alt_amsl_m) / 15.0
    assert climb >= 2.0
    assert all(abs(s.airspeed_m_s - 15.0) < 1.5 for s in steady)


def test_take_off_from_rest_reaches_100_m_agl_wings_level_on_heading() -> None:
    model = JSBSimModel()
    heading = math.radians(250.0)
    state, controller = _ground_start(model, heading)
    assert state.on_ground

    def target(s: VehicleState) -> ControlTarget:
        phase = ControlPhase.GROUND_ROLL if s.alt_agl_m < 5.0 else ControlPhase.CLIMB
        return ControlTarget(
            phase=phase,
            heading_rad=heading,
            airspeed_m_s=15.0,
            climb_rate_limit_m_s=3.0,
            altitude_amsl_m=HOME.alt_amsl_m + 100.0,
        )

    states = _fly(model, controller, state, target, 45.0)
    liftoff = next(i for i, s in enumerate(states) if not s.on_ground)
    roll_distance = math.hypot(*states[liftoff].pos_ned_m[:2])
    assert roll_distance < 40.0
    assert max(s.alt_agl_m for s in states) >= 100.0
    assert all(abs(s.roll_rad) < math.radians(5.0) for s in states)
    assert all(
        abs(math.remainder(s.yaw_rad - heading, math.tau)) < math.radians(5.0) for s in states
    )
    assert min(s.airspeed_m_s for s in states[liftoff:]) > 11.0


def test_land_glides_flares_touches_down_gently_and_stops() -> None:
    model = JSBSimModel()
    state, controller = _air_start(model, alt_amsl_m=HOME.alt_amsl_m + 40.0, heading_rad=0.0)
    target = ControlTarget(
        phase=ControlPhase.LAND,
        airspeed_m_s=13.0,
        heading_rad=0.0,
        altitude_amsl_m=HOME.alt_amsl_m,
        ground_amsl_m=HOME.alt_amsl_m,
    )
    states = _fly(model, controller, state, lambda _s: target, 60.0)
    touchdown = next(i for i, s in enumerate(states) if s.on_ground)
    before = states[touchdown - 1]
    assert before.vel_ned_m_s[2] < 1.0  # sink rate at touchdown, m/s
    assert before.pitch_rad > -math.radians(1.0)  # main wheels first, not the nose wheel
    assert all(s.on_ground for s in states[touchdown + STEPS_PER_S :])
    assert states[-1].airspeed_m_s < 0.1
    assert abs(states[-1].roll_rad) < math.radians(2.0)


def test_idle_holds_the_aircraft_with_brakes_and_no_throttle() -> None:
    model = JSBSimModel()
    state, controller = _ground_start(model, 0.0)
    command = controller.update(state, ControlTarget(phase=ControlPhase.IDLE))
    assert command == ActuatorCommand(brake=1.0)
    states = _fly(model, controller, state, lambda _s: ControlTarget(phase=ControlPhase.IDLE), 5)
    assert math.dist(states[-1].pos_ned_m, state.pos_ned_m) < 0.01


def test_controller_is_deterministic() -> None:
    def run() -> list[ActuatorCommand]:
        model = JSBSimModel()
        state, controller = _air_start(model, Wind(speed_m_s=4.0, from_deg=200.0))
        out = []
        target = _cruise(roll_rad=-0.4, alt_m=CRUISE_ALT_M + 10.0)
        for _ in range(5 * STEPS_PER_S):
            command = controller.update(state, target(state))
            state = model.step(command)
            out.append(command)
        return out

    assert run() == run()


def test_gains_for_known_and_unknown_aircraft() -> None:
    assert gains_for("airsitl_uav") == ControlGains()
    assert gains_for("some_other_plane") == ControlGains()
    assert gains_for("c172p").ref_airspeed_m_s > 30.0
    assert gains_for("J3Cub").ref_airspeed_m_s > 20.0


def test_cruise_in_moderate_turbulence_stays_near_altitude_and_speed() -> None:
    model = JSBSimModel(seed=3)
    wind = Wind(speed_m_s=5.0, from_deg=300.0, turbulence=0.4)
    state, controller = _air_start(model, wind)
    states = _fly(model, controller, state, _cruise(roll_rad=0.3), 60.0)
    assert max(abs(s.alt_amsl_m - CRUISE_ALT_M) for s in states) < 10.0
    assert min(s.airspeed_m_s for s in states) > 11.0
    assert max(abs(s.roll_rad - 0.3) for s in states[5 * STEPS_PER_S :]) < math.radians(15.0)


def test_glide_slope_then_flare_touches_down_near_the_aim_point() -> None:
    """As guidance lands: CRUISE down a 5 degree slope, the LAND law below 8 m."""
    model = JSBSimModel()
    state, controller = _air_start(model, alt_amsl_m=HOME.alt_amsl_m + 40.0, heading_rad=0.0)
    slope = math.radians(5.0)
    aim_north_m = 40.0 / math.tan(slope)
    errors = []
    touchdown_north_m = math.nan
    for _ in range(60 * STEPS_PER_S):
        slope_alt = HOME.alt_amsl_m + max(0.0, aim_north_m - state.pos_ned_m[0]) * math.tan(slope)
        low = state.alt_agl_m < 8.0 or state.on_ground
        if 10.0 < state.alt_agl_m < 30.0:
            errors.append(state.alt_amsl_m - slope_alt)
        target = ControlTarget(
            phase=ControlPhase.LAND if low else ControlPhase.CRUISE,
            altitude_amsl_m=slope_alt,
            airspeed_m_s=13.0,
            heading_rad=0.0,
            ground_amsl_m=HOME.alt_amsl_m,
        )
        before = state
        state = model.step(controller.update(state, target))
        if state.on_ground and math.isnan(touchdown_north_m):
            touchdown_north_m = state.pos_ned_m[0]
            assert before.vel_ned_m_s[2] < 1.0
    assert max(abs(e) for e in errors) < 1.5
    assert abs(touchdown_north_m - aim_north_m) < 60.0
    assert state.on_ground
    assert state.airspeed_m_s < 0.1


def test_take_off_in_a_5_m_s_crosswind_stays_near_the_runway_heading() -> None:
    model = JSBSimModel()
    ic = InitialCondition(
        lat_deg=HOME.lat_deg, lon_deg=HOME.lon_deg, alt_amsl_m=HOME.alt_amsl_m, heading_rad=0.0
    )
    state = model.reset(HOME, ic, Wind(speed_m_s=5.0, from_deg=90.0))
    controller = Controller()

    def target(s: VehicleState) -> ControlTarget:
        phase = ControlPhase.GROUND_ROLL if s.alt_agl_m < 5.0 else ControlPhase.CLIMB
        return ControlTarget(phase=phase, heading_rad=0.0, airspeed_m_s=15.0)

    states = _fly(model, controller, state, target, 30.0)
    on_ground = [s for s in states if s.on_ground]
    assert on_ground
    assert all(abs(s.yaw_rad) < math.radians(20.0) for s in on_ground)
    assert all(abs(s.pos_ned_m[1]) < 2.0 for s in on_ground)  # stays on a 4 m wide strip
    assert states[-1].alt_agl_m > 60.0
    assert all(abs(s.roll_rad) < math.radians(8.0) for s in states)


def test_the_targets_pitch_limits_bound_the_climb_attitude() -> None:
    """FW_P_LIM_MAX reaches the controller through ControlTarget and caps a climb."""

    def climb(limit_deg: float) -> float:
        model = JSBSimModel()
        state, controller = _air_start(model)
        target = ControlTarget(
            phase=ControlPhase.CRUISE,
            altitude_amsl_m=CRUISE_ALT_M + 150.0,
            airspeed_m_s=15.0,
            climb_rate_limit_m_s=6.0,
            pitch_max_rad=math.radians(limit_deg),
        )
        states = _fly(model, controller, state, lambda _s: target, 15.0)
        return max(math.degrees(s.pitch_rad) for s in states)

    free = climb(90.0)
    limited = climb(4.0)
    assert free > 8.0  # unconstrained, the climb pitches up well beyond 4 degrees
    assert limited < 4.0 + 1.5  # the command is capped; the attitude overshoots it a little
