"""serve: a mission with a waypoint before its NAV_TAKEOFF is accepted on upload (as PX4) and
refused at start: DO_SET_MODE AUTO.MISSION answers DENIED with PX4's STATUSTEXT."""

from __future__ import annotations

import time

import pytest
from gcs import PX4_MISSION, SAFETY_S, Gcs, serve
from pymavlink import mavutil

from air_sitl.mission.items import MavCmd, MissionItem

M = mavutil.mavlink
pytestmark = pytest.mark.integration


def test_start_refused_with_px4_statustext() -> None:
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", "0") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        items = [
            MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=47.4, lon_deg=8.546, alt_m=50),
            MissionItem(command=MavCmd.NAV_TAKEOFF, lat_deg=47.3977, lon_deg=8.5456, alt_m=40),
            MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=47.402, lon_deg=8.546, alt_m=50),
        ]
        assert gcs.upload(items) == M.MAV_MISSION_ACCEPTED  # PX4 accepts the upload
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_DENIED
        # STATUSTEXT carries 50 characters: a longer text comes in chunks (QGC joins them).
        deadline = time.monotonic() + SAFETY_S  # safety only: a busy machine never reaches it
        while "takeoff not first" not in "".join(gcs.texts) and time.monotonic() < deadline:
            gcs.recv(["STATUSTEXT", "HEARTBEAT"], 1.0)
        assert "Mission rejected: takeoff not first waypoint item" in "".join(gcs.texts)
        assert gcs.command(M.MAV_CMD_MISSION_START) == M.MAV_RESULT_DENIED
        gcs.close()
