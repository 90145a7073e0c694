"""VFR_HUD's throttle is the throttle flown; SYS_STATUS and BATTERY_STATUS carry the battery
model; the low-battery failsafe (COM_LOW_BAT_ACT) acts as PX4's."""

from __future__ import annotations

import math

import pytest
from gcs import Gcs
from inproc import running_vehicle
from pymavlink.dialects.v20 import common as mavlink2

from air_sitl.state import FlightMode, GeoPoint

M = mavlink2
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
pytestmark = pytest.mark.integration


def test_throttle_battery_and_the_low_battery_failsafe() -> None:
    with running_vehicle(["udpin:127.0.0.1:0"], HOME, speed=20.0) as vehicle:
        gcs = Gcs(f"udpout:127.0.0.1:{vehicle.endpoint.links[0].local_address[1]}")
        gcs.connect()
        status = gcs.recv(["SYS_STATUS"])
        assert 16_000 <= status.voltage_battery <= 16_300  # 4 cells at 4.05 V, idle
        assert status.battery_remaining == 100
        # A small pack, and PX4's "return at critical, land at emergency".
        assert gcs.set_param("BAT1_CAPACITY", 150.0) == pytest.approx(150.0)
        gcs.set_param("COM_LOW_BAT_ACT", 3)
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        nan = math.nan
        assert gcs.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, nan) == (
            M.MAV_RESULT_ACCEPTED
        )
        hud = gcs.recv(["VFR_HUD"])
        while hud.throttle == 0:  # the take-off roll begins at the next updates
            hud = gcs.recv(["VFR_HUD"])
        assert 50 <= hud.throttle <= 100
        pack = gcs.recv(["BATTERY_STATUS"])
        assert pack.current_battery > 0 and pack.current_consumed >= 0
        assert pack.voltages[0] < 4100 and pack.voltages[4] == 65535  # 4 cells, mV
        # The pack runs down: critical -> RTL, emergency -> land; the GCS is told of each.
        critical = gcs.wait_text("Critical battery level")
        emergency = gcs.wait_text("Emergency battery level")
        assert critical.endswith(": RTL") and emergency.endswith(": landing")
        assert gcs.texts.index(critical) < gcs.texts.index(emergency)
        # Every mode flown, in simulated time (RTL may last less than a wall-clock heartbeat);
        # the mode set with the text shows from the next step: let a simulated second pass.
        gcs.collect(["SYS_STATUS"], 1.0)
        modes = vehicle.truth.modes
        assert FlightMode.RTL in modes and FlightMode.LAND in modes
        assert modes.index(FlightMode.RTL) < modes.index(FlightMode.LAND)
        status = gcs.recv(["SYS_STATUS"])
        assert status.battery_remaining <= 5 and status.current_battery > 0
        gcs.close()
