"""Uploading a mission in flight, as PX4: an identical re-upload changes nothing; a changed
mission keeps the current index unless an uploaded item is flagged current; no item is
reported reached again."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import pytest
from gcs import Gcs
from inproc import running_vehicle
from pymavlink.dialects.v20 import common as mavlink2

from air_sitl.mission.plan_file import load_mission

M = mavlink2
UC200 = Path(__file__).resolve().parents[2] / "missions" / "UC-200.plan"
pytestmark = pytest.mark.integration


def until_current(gcs: Gcs, seq: int) -> Any:
    """Wait (on telemetry) until MISSION_CURRENT reaches ``seq``."""
    while True:
        msg = gcs.recv(["MISSION_CURRENT"])
        assert msg is not None
        if msg.seq >= seq:
            return msg


def after_upload(gcs: Gcs, sim_s: float) -> tuple[list[int], list[int]]:
    """Items reported reached and MISSION_CURRENT seqs over the next simulated seconds."""
    msgs = gcs.collect(["MISSION_ITEM_REACHED", "MISSION_CURRENT"], sim_s)
    reached = [m.seq for m in msgs if m.get_type() == "MISSION_ITEM_REACHED"]
    current = [m.seq for m in msgs if m.get_type() == "MISSION_CURRENT"]
    return reached, current


def test_reuploads_in_flight_keep_the_mission_going() -> None:
    mission = load_mission(UC200)
    home = mission.planned_home
    assert home is not None
    # Everything below waits on telemetry by simulated time: the speed only says how fast
    # the 170 simulated seconds to item 3 go by (a loaded machine just runs slower).
    with running_vehicle(["udpin:127.0.0.1:0"], home, speed=50.0, mission=mission) as vehicle:
        gcs = Gcs(f"udpout:127.0.0.1:{vehicle.endpoint.links[0].local_address[1]}")
        gcs.connect()
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_ACCEPTED
        here = until_current(gcs, 3).seq
        # Identical items (with item 0 flagged current, as ground stations send it): ignored.
        assert gcs.upload(mission.items, current=0) == M.MAV_MISSION_ACCEPTED
        reached, current = after_upload(gcs, 3.0)
        assert [s for s in reached if s < here] == [], reached
        assert current and min(current) >= here, current
        # A changed mission, nothing flagged current: the current index is kept.
        here = current[-1]
        last = len(mission.items) - 1
        changed = list(mission.items)
        changed[last] = dataclasses.replace(changed[last], alt_m=changed[last].alt_m + 5.0)
        assert gcs.upload(changed, current=None) == M.MAV_MISSION_ACCEPTED
        reached, current = after_upload(gcs, 3.0)
        assert [s for s in reached if s < here] == [], reached
        assert current and min(current) >= here, current
        # A changed mission with an item flagged current: that item is flown next.
        changed[last] = dataclasses.replace(changed[last], alt_m=changed[last].alt_m + 5.0)
        assert gcs.upload(changed, current=2) == M.MAV_MISSION_ACCEPTED
        reached, current = after_upload(gcs, 3.0)
        assert current and current[-1] in (2, 3), current  # 2 then on, as flown
        assert 0 not in reached and 1 not in reached, reached
        gcs.close()
