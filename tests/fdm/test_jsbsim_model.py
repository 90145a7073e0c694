"""JSBSimModel with real JSBSim: the airsitl_uav envelope, the adapter's frames and units."""

from __future__ import annotations

import math

import pytest

from air_sitl.clock import PHYSICS_STEP_NS
from air_sitl.errors import AircraftError
from air_sitl.fdm.base import InitialCondition, Wind
from air_sitl.fdm.jsbsim_model import JSBSimModel, available_aircraft
from air_sitl.frames import geodetic2ned, quat2euler
from air_sitl.state import ActuatorCommand, GeoPoint, VehicleState

# Real JSBSim flights (fast: the whole module takes a few seconds).
pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
STEPS_PER_S = 1_000_000_000 // PHYSICS_STEP_NS


def _air_start(airspeed_m_s: float, heading_rad: float = 0.7) -> InitialCondition:
    return InitialCondition(
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=HOME.alt_amsl_m + 300.0,
        heading_rad=heading_rad,
        airspeed_m_s=airspeed_m_s,
        on_ground=False,
    )


def _ground_start(heading_rad: float = 1.2) -> InitialCondition:
    return InitialCondition(
        lat_deg=HOME.lat_deg,
        lon_deg=HOME.lon_deg,
        alt_amsl_m=HOME.alt_amsl_m,
        heading_rad=heading_rad,
    )


def _hold(model: JSBSimModel, command: ActuatorCommand, seconds: float) -> list[VehicleState]:
    return [model.step(command) for _ in range(int(seconds * STEPS_PER_S))]


def test_available_aircraft_lists_ours_first_and_the_wheels() -> None:
    names = available_aircraft()
    assert names[0] == "airsitl_uav"
    assert {"c172p", "J3Cub"} <= set(names)


def test_unknown_aircraft_raises_one_line_error_naming_it() -> None:
    with pytest.raises(AircraftError) as info:
        JSBSimModel("no_such_plane")
    message = str(info.value)
    assert "no_such_plane" in message
    assert "airsitl_uav" in message
    assert "\n" not in message


def test_level_trim_at_15_m_s_holds_altitude_hands_off_for_60_s() -> None:
    model = JSBSimModel()
    start = model.reset(HOME, _air_start(15.0), Wind())
    trim = model.trim_command
    assert 0.3 < trim.throttle < 0.9
    assert abs(trim.elevator) < 0.3
    assert start.airspeed_m_s == pytest.approx(15.0, abs=0.01)
    assert start.sim_time_ns == 0
    states = _hold(model, trim, 60.0)
    assert states[-1].sim_time_ns == 60 * 1_000_000_000
    alt_errors = [abs(s.alt_amsl_m - start.alt_amsl_m) for s in states]
    assert max(alt_errors) < 2.0
    assert all(abs(s.airspeed_m_s - 15.0) < 1.0 for s in states)
    assert all(abs(s.roll_rad) < math.radians(3.0) for s in states)


def test_stall_is_at_or_below_11_m_s_and_level_flight_fails_far_below_it() -> None:
    model = JSBSimModel()
    state = model.reset(HOME, _air_start(11.0), Wind())  # trims: level flight at 11 m/s
    assert model.trim_command.throttle < 1.0
    states = _hold(model, model.trim_command, 10.0)
    assert abs(states[-1].alt_amsl_m - state.alt_amsl_m) < 2.0
    with pytest.raises(AircraftError, match=r"7\.0 m/s"):
        model.reset(HOME, _air_start(7.0), Wind())  # beyond CL_max: no level trim


def test_top_level_speed_is_at_least_22_m_s_at_full_throttle() -> None:
    model = JSBSimModel()
    model.reset(HOME, _air_start(22.0), Wind())
    assert model.trim_command.throttle < 1.0  # level at 22 m/s needs less than full power


def test_at_rest_on_the_ground_it_stays_put_and_feels_gravity() -> None:
    model = JSBSimModel()
    start = model.reset(HOME, _ground_start(), Wind())
    assert start.on_ground
    assert start.alt_agl_m == pytest.approx(start.alt_amsl_m - HOME.alt_amsl_m)
    states = _hold(model, ActuatorCommand(brake=1.0), 10.0)
    last = states[-1]
    assert all(s.on_ground for s in states)
    assert math.dist(last.pos_ned_m, start.pos_ned_m) < 0.01
    assert abs(last.yaw_rad - 1.2) < 1e-3
    fx, fy, fz = last.specific_force_frd_m_s2
    assert math.sqrt(fx * fx + fy * fy + fz * fz) == pytest.approx(9.81, abs=0.05)
    assert fz < -9.7
    assert last.airspeed_m_s < 0.01


def test_state_frames_agree_with_air_sitl_frames() -> None:
    model = JSBSimModel()
    model.reset(HOME, _air_start(15.0, heading_rad=-2.5), Wind())
    state = _hold(model, model.trim_command, 20.0)[-1]
    roll, pitch, yaw = quat2euler(state.q_body_to_ned_wxyz)
    assert (roll, pitch, yaw) == pytest.approx(
        (state.roll_rad, state.pitch_rad, state.yaw_rad), abs=1e-9
    )
    assert -math.pi <= state.yaw_rad < math.pi
    assert state.yaw_rad == pytest.approx(-2.5, abs=0.05)
    ned = geodetic2ned(
        state.lat_deg,
        state.lon_deg,
        state.alt_amsl_m,
        HOME.lat_deg,
        HOME.lon_deg,
        HOME.alt_amsl_m,
    )
    assert state.pos_ned_m == pytest.approx(ned, abs=1e-3)
    # Flying at heading -2.5 rad for 20 s at 15 m/s.
    assert math.hypot(state.pos_ned_m[0], state.pos_ned_m[1]) == pytest.approx(300.0, rel=0.02)
    vn, ve, _ = state.vel_ned_m_s
    assert math.atan2(ve, vn) == pytest.approx(-2.5, abs=0.02)


def test_wind_moves_the_trimmed_aircraft_with_the_air() -> None:
    model = JSBSimModel()
    # 5 m/s FROM the west blows toward the east; the aircraft heads north.
    start = model.reset(HOME, _air_start(15.0, heading_rad=0.0), Wind(speed_m_s=5.0, from_deg=270))
    assert start.airspeed_m_s == pytest.approx(15.0, abs=0.05)
    assert start.vel_ned_m_s[0] == pytest.approx(15.0, abs=0.1)
    assert start.vel_ned_m_s[1] == pytest.approx(5.0, abs=0.1)
    states = _hold(model, model.trim_command, 20.0)
    assert abs(states[-1].alt_amsl_m - start.alt_amsl_m) < 2.0
    assert states[-1].airspeed_m_s == pytest.approx(15.0, abs=0.5)


def test_same_inputs_give_identical_states() -> None:
    def run() -> list[VehicleState]:
        model = JSBSimModel()
        model.reset(HOME, _air_start(16.0), Wind(speed_m_s=3.0, from_deg=40.0))
        out = []
        for i in range(2 * STEPS_PER_S):
            out.append(
                model.step(
                    ActuatorCommand(aileron=0.2 * math.sin(i * 0.01), elevator=-0.05, throttle=0.7)
                )
            )
        return out

    assert run() == run()


def test_reset_starts_over_from_the_same_state() -> None:
    model = JSBSimModel()
    first = model.reset(HOME, _ground_start(), Wind())
    _hold(model, ActuatorCommand(throttle=1.0), 3.0)
    assert model.reset(HOME, _ground_start(), Wind()) == first


@pytest.mark.parametrize("aircraft", ["c172p", "J3Cub"])
def test_a_wheel_aircraft_loads_rests_and_flies(aircraft: str) -> None:
    model = JSBSimModel(aircraft)
    rest = model.reset(HOME, _ground_start(), Wind())
    assert rest.on_ground
    states = _hold(model, ActuatorCommand(brake=1.0), 1.0)
    assert states[-1].on_ground
    assert math.dist(states[-1].pos_ned_m, rest.pos_ned_m) < 0.05
    airspeed = 50.0 if aircraft == "c172p" else 30.0
    start = model.reset(HOME, _air_start(airspeed), Wind())
    assert not start.on_ground
    states = _hold(model, model.trim_command, 5.0)
    assert abs(states[-1].alt_amsl_m - start.alt_amsl_m) < 5.0


def _gusty_run(seed: int) -> list[VehicleState]:
    model = JSBSimModel(seed=seed)
    model.reset(HOME, _air_start(15.0), Wind(speed_m_s=4.0, from_deg=120.0, turbulence=0.3))
    return _hold(model, model.trim_command, 5.0)


def test_turbulence_is_seeded_repeatable_and_really_gusty() -> None:
    first = _gusty_run(seed=7)
    assert first == _gusty_run(seed=7)
    other = _gusty_run(seed=8)
    assert first != other
    rates = [s.rate_frd_rad_s[0] for s in first]
    assert max(rates) - min(rates) > 0.02  # gusts shake the aircraft
    calm = JSBSimModel()
    calm.reset(HOME, _air_start(15.0), Wind(speed_m_s=4.0, from_deg=120.0))
    calm_rates = [s.rate_frd_rad_s[0] for s in _hold(calm, calm.trim_command, 5.0)]
    assert max(calm_rates) - min(calm_rates) < 5e-3


def test_turbulence_above_1_is_refused() -> None:
    with pytest.raises(AircraftError, match="turbulence"):
        JSBSimModel().reset(HOME, _air_start(15.0), Wind(turbulence=1.5))


def test_phugoid_after_an_elevator_pulse_dies_out_hands_off() -> None:
    model = JSBSimModel()
    model.reset(HOME, _air_start(15.0), Wind())
    trim = model.trim_command
    pulse = ActuatorCommand(
        aileron=trim.aileron, elevator=trim.elevator - 0.1, rudder=trim.rudder,
        throttle=trim.throttle,
    )  # fmt: skip
    _hold(model, pulse, 1.0)
    speeds = [s.airspeed_m_s for s in _hold(model, trim, 40.0)]
    first = speeds[: 10 * STEPS_PER_S]
    last = speeds[30 * STEPS_PER_S :]
    assert max(first) - min(first) > 1.0  # the pulse did excite the phugoid
    assert max(last) - min(last) < 0.1 * (max(first) - min(first))
    assert abs(speeds[-1] - 15.0) < 0.1
