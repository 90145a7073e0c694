"""GPS_RAW_INT ``cog`` on a leg flown due east: about 9000 cdeg (MAVLink: course over ground,
0 = north, clockwise), and in agreement with GLOBAL_POSITION_INT ``hdg`` and with the
velocity GLOBAL_POSITION_INT reports (vx north, vy east). North and east swapped gives 0."""

from __future__ import annotations

import math

import pytest
from gcs import PX4_MISSION, Gcs, serve
from pymavlink import mavutil

from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd, MissionItem

M = mavutil.mavlink
pytestmark = pytest.mark.integration
HOME = (47.397742, 8.545594, 488.0)  # serve's default home (PX4 SITL)


def _east(metres: float, alt: float, cmd: int = MavCmd.NAV_WAYPOINT) -> MissionItem:
    lat, lon, _ = ned2geodetic(0.0, metres, 0.0, *HOME)
    return MissionItem(command=cmd, lat_deg=lat, lon_deg=lon, alt_m=alt)


def _angle_diff_cdeg(a: float, b: float) -> float:
    return abs((a - b + 18000.0) % 36000.0 - 18000.0)


def test_cog_on_a_leg_due_east() -> None:
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", "0", "--sensor-noise", "0") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        items = [_east(0.0, 60.0, MavCmd.NAV_TAKEOFF), _east(600.0, 60.0), _east(4000.0, 60.0)]
        assert gcs.upload(items) == M.MAV_MISSION_ACCEPTED
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        # Wait (in simulated time) for the long leg east: waypoint 1 reached.
        while True:
            current = gcs.recv(["MISSION_CURRENT"], 60.0)
            assert current is not None, "no MISSION_CURRENT"
            if current.seq == 2:
                break
        gcs.collect(["HEARTBEAT"], 10.0)  # settle on the leg
        msgs = gcs.collect(["GPS_RAW_INT", "GLOBAL_POSITION_INT"], 20.0)
        gcs.close()
    raw = [m for m in msgs if m.get_type() == "GPS_RAW_INT"]
    pos = [m for m in msgs if m.get_type() == "GLOBAL_POSITION_INT"]
    assert len(raw) >= 10 and len(pos) >= 10
    for m in raw:
        assert m.vel > 1000  # cm/s: flying
        assert _angle_diff_cdeg(m.cog, 9000.0) < 500.0, m.cog
    for m in pos:
        assert _angle_diff_cdeg(m.hdg, 9000.0) < 800.0, m.hdg  # heading: crab angle only
        course = math.degrees(math.atan2(m.vy, m.vx)) * 100.0 % 36000.0
        assert _angle_diff_cdeg(course, 9000.0) < 500.0, (m.vx, m.vy)
    mean_cog = sum(m.cog for m in raw) / len(raw)
    mean_hdg = sum(m.hdg for m in pos) / len(pos)
    assert _angle_diff_cdeg(mean_cog, mean_hdg) < 500.0
