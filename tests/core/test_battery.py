"""The propulsion battery: energy from the throttle flown, voltage sag, PX4 warning levels and
COM_LOW_BAT_ACT, and its block in summary.json."""

from __future__ import annotations

import dataclasses

import pytest
from vehicle_states import airborne_state

from air_sitl import battery
from air_sitl.battery import Battery, BatterySpec, electrical_power_w, terminal_voltage_v
from air_sitl.flightlog import FlightStats
from air_sitl.state import ActuatorCommand, mission_sample

NS = 1_000_000_000


def fly(pack: Battery, throttle: float, seconds: int, step_s: float = 0.01) -> battery.BatteryState:
    state = pack.step(0, throttle)
    steps = round(seconds / step_s)
    for i in range(1, steps + 1):
        state = pack.step(round(i * step_s * NS), throttle)
    return state


def test_energy_follows_the_throttle_and_the_voltage_sags_with_current() -> None:
    spec = BatterySpec()
    idle, cruise, full = (fly(Battery(spec), t, 60) for t in (0.0, 0.6, 1.0))
    assert idle.consumed_wh < cruise.consumed_wh < full.consumed_wh
    # Energy is power x time: one minute at 60 % throttle.
    assert cruise.consumed_wh == pytest.approx(electrical_power_w(0.6) / 60, rel=0.01)
    assert cruise.remaining == pytest.approx(1 - cruise.consumed_mah / spec.capacity_mah)
    # Under load the terminal voltage drops below the open-circuit voltage (V = Voc - I R).
    assert full.voltage_v < cruise.voltage_v < idle.voltage_v <= spec.cells * spec.v_charged_cell
    v_oc = 16.0
    v = terminal_voltage_v(v_oc, 0.02, 500.0)
    assert v_oc - v == pytest.approx((500.0 / v) * 0.02, rel=1e-6)


def test_a_pack_drains_to_empty_and_the_voltage_falls() -> None:
    small = BatterySpec(capacity_mah=100.0)
    pack = Battery(small)
    start = fly(pack, 0.6, 1)
    end = fly(pack, 0.6, 120)
    assert end.remaining < start.remaining
    assert end.voltage_v < start.voltage_v


@pytest.mark.parametrize(
    ("remaining", "level"),
    [
        (0.5, battery.LEVEL_OK),
        (0.15, battery.LEVEL_LOW),
        (0.06, battery.LEVEL_CRITICAL),
        (0.01, battery.LEVEL_EMERGENCY),
    ],
)
def test_warning_levels_follow_px4_thresholds(remaining: float, level: int) -> None:
    assert battery.warning_level(remaining, 0.15, 0.07, 0.05) == level


def test_com_low_bat_act_as_px4() -> None:
    act = battery.failsafe_action
    assert act(battery.LEVEL_EMERGENCY, 0) == battery.ACTION_NONE  # warnings only
    assert act(battery.LEVEL_LOW, 2) == battery.ACTION_NONE
    assert act(battery.LEVEL_CRITICAL, 2) == battery.ACTION_LAND
    assert act(battery.LEVEL_CRITICAL, 3) == battery.ACTION_RETURN
    assert act(battery.LEVEL_EMERGENCY, 3) == battery.ACTION_LAND
    assert act(battery.LEVEL_CRITICAL, 1) == battery.ACTION_RETURN


def test_summary_has_a_battery_block() -> None:
    stats = FlightStats(1)
    pack = Battery(BatterySpec())
    for i in range(200):
        t = i * 10_000_000
        state = airborne_state(
            t, lat_deg=47.4, lon_deg=8.5, alt_amsl_m=600, alt_agl_m=100, pos_ned_m=(0, 0, -100)
        )
        sample = dataclasses.replace(
            mission_sample(state),
            actuators=ActuatorCommand(throttle=0.6),
            battery=pack.step(t, 0.6),
        )
        stats.add(sample)
    block = stats.summary(1.0)["battery"]
    assert block["consumed_mah"] > 0 and block["consumed_wh"] > 0
    assert 0.99 < block["remaining"] < 1.0
    assert block["min_voltage_v"] <= block["voltage_v"]
    assert FlightStats(1).summary(1.0)["battery"] is None
