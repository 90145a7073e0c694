"""MAV_FRAME_GLOBAL_TERRAIN_ALT(_INT) items: refused without a terrain model, accepted with one
(``--dem``); their altitude is the surface's at the item plus their height."""

from __future__ import annotations

from pathlib import Path

import pytest
import short_plans

from air_sitl.errors import PlanError
from air_sitl.mission.geometry import item_altitude_amsl
from air_sitl.mission.items import MavCmd, MavFrame, MissionItem
from air_sitl.mission.plan_file import load_mission
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=47.0, lon_deg=8.0, alt_amsl_m=400.0)


def _plan(tmp_path: Path, frame: int) -> Path:
    items = [(22, 3, 47.0, 8.0, 40.0), (16, frame, 47.01, 8.0, 120.0)]
    return short_plans.write_items_plan(tmp_path / "terrain.plan", HOME, items)


@pytest.mark.parametrize("frame", [10, 11])
def test_a_plan_with_terrain_frames_needs_a_terrain_model(tmp_path: Path, frame: int) -> None:
    plan = _plan(tmp_path, frame)
    with pytest.raises(PlanError, match=r"item 1: terrain-relative frame .* fly with --dem"):
        load_mission(plan)
    mission = load_mission(plan, terrain=True)
    assert mission.items[1].frame == frame and mission.items[1].alt_m == 120.0


def test_terrain_altitudes_are_above_the_surface_at_the_item() -> None:
    def surface(lat_deg: float, lon_deg: float) -> float:
        return 500.0 + 1000.0 * (lat_deg - 47.0)  # rising 10 m per 0.01 degree north

    item = MissionItem(command=MavCmd.NAV_WAYPOINT, frame=MavFrame.GLOBAL_TERRAIN_ALT,
                       lat_deg=47.01, lon_deg=8.0, alt_m=120.0)  # fmt: skip
    assert item_altitude_amsl(item, HOME, surface) == pytest.approx(510.0 + 120.0)
    # No position (0, 0 is "here"): the ground at home, which is home's altitude.
    here = MissionItem(command=MavCmd.NAV_TAKEOFF, frame=MavFrame.GLOBAL_TERRAIN_ALT, alt_m=40.0)
    assert item_altitude_amsl(here, HOME, surface) == 440.0
    relative = MissionItem(command=MavCmd.NAV_WAYPOINT, frame=MavFrame.GLOBAL_RELATIVE_ALT,
                           lat_deg=47.01, lon_deg=8.0, alt_m=120.0)  # fmt: skip
    assert item_altitude_amsl(relative, HOME, surface) == 520.0
