"""``air-sitl serve`` after a crash: the vehicle disarms and says where and why, once.

A real served vehicle (a process) flown by pymavlink into the ground: a waypoint 30 m below
ground outside a landing (a waypoint at ground level was not a sure crash: the onboard
estimate's baro error decided whether the wheels touched). Before, the served vehicle
flew on armed, motor running, into the ground with nothing said.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import short_plans
from gcs import PX4_MISSION, Gcs, serve
from pymavlink import mavutil

from air_sitl.frames import ned2geodetic
from air_sitl.state import GeoPoint

M = mavutil.mavlink
HOME = GeoPoint(lat_deg=54.68, lon_deg=25.28, alt_amsl_m=120.0)
pytestmark = pytest.mark.integration


def crash_plan(tmp_path: Path) -> Path:
    """Take off to 40 m, fly 600 m north, then to a waypoint 30 m underground 800 m further."""
    placed = []
    for cmd, north_m, alt_m in ((22, 0, 40), (16, 600, 40), (16, 1400, -30), (16, 2000, 40)):
        lat, lon, _ = ned2geodetic(north_m, 0.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
        placed.append((cmd, 3, lat, lon, alt_m))
    return short_plans.write_items_plan(tmp_path / "crash.plan", HOME, placed)


def test_a_served_vehicle_that_crashes_disarms_and_says_why(tmp_path: Path) -> None:
    plan = crash_plan(tmp_path)
    with serve("--mavlink", "udpin:127.0.0.1:0", "--plan", str(plan), "--speed", "50") as served:
        gcs = Gcs(f"udpout:127.0.0.1:{served.ports[0]}")
        try:
            gcs.connect()
            assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_ACCEPTED
            assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
            text = gcs.wait_whole_text("Crashed at")
            assert "outside a landing" in text and "disarmed" in text
            # The heartbeats that follow say disarmed; the vehicle stays on the ground.
            heartbeat = gcs.recv(["HEARTBEAT"])
            while heartbeat is not None and heartbeat.get_srcComponent() != 1:
                heartbeat = gcs.recv(["HEARTBEAT"])
            assert heartbeat is not None
            assert not heartbeat.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
            position = gcs.recv(["GLOBAL_POSITION_INT"])
            assert position is not None and position.relative_alt < 5_000  # mm above home
            # Said once: a later stretch of telemetry brings no second crash text.
            gcs.collect(["GLOBAL_POSITION_INT"], 5.0)
            assert sum("Crashed at" in t for t in gcs.texts) == 1
            # Where: on the leg down to the ground-level waypoint.
            north_m = (position.lat / 1e7 - HOME.lat_deg) * 111_320.0
            assert 600.0 < north_m < 1500.0
        finally:
            gcs.close()
        code, _err = served.stop()
    assert code == 0
