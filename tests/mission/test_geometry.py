"""Mission geometry: where items are, loiter circles, the start point, DO_JUMP walks."""

from __future__ import annotations

import math

import pytest
from mission_samples import LOITER_TURNS

from air_sitl.mission.geometry import (
    MAX_DO_STEPS,
    first_flown_item,
    item_altitude_amsl,
    item_point,
    loiter_geometry,
    next_nav_index,
)
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.68, lon_deg=25.28, alt_amsl_m=120.0)


def _item(command: int, **kw: float) -> MissionItem:
    return MissionItem(command=command, **kw)  # type: ignore[arg-type]


def _jump(target: int, repeat: int) -> MissionItem:
    return MissionItem(command=MavCmd.DO_JUMP, frame=MavFrame.MISSION, param1=target, param2=repeat)


@pytest.mark.parametrize(
    ("frame", "expected_m"),
    [
        (MavFrame.GLOBAL_RELATIVE_ALT, 320.0),
        (MavFrame.GLOBAL_RELATIVE_ALT_INT, 320.0),
        (MavFrame.GLOBAL, 200.0),
        (MavFrame.GLOBAL_INT, 200.0),
    ],
)
def test_relative_frames_add_home_altitude(frame: int, expected_m: float) -> None:
    item = MissionItem(command=MavCmd.NAV_WAYPOINT, frame=frame, alt_m=200.0)
    assert item_altitude_amsl(item, HOME) == expected_m


def test_item_point_is_north_east_of_home() -> None:
    north = MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=54.69, lon_deg=25.28, alt_m=100.0)
    n, e, alt = item_point(north, HOME)
    assert n == pytest.approx(1113.0, abs=5.0)
    assert e == pytest.approx(0.0, abs=1e-6)
    assert alt == 220.0


@pytest.mark.parametrize(("lat", "lon"), [(0.0, 0.0), (math.nan, 25.0), (54.0, math.inf)])
def test_item_without_position_has_nan_north_east(lat: float, lon: float) -> None:
    n, e, alt = item_point(_item(MavCmd.NAV_LAND, lat_deg=lat, lon_deg=lon, alt_m=0.0), HOME)
    assert math.isnan(n) and math.isnan(e)
    assert alt == HOME.alt_amsl_m


@pytest.mark.parametrize(
    ("command", "params", "expected"),
    [
        (MavCmd.NAV_LOITER_UNLIM, {"param3": 150.0}, (150.0, 1)),
        (MavCmd.NAV_LOITER_TURNS, {"param3": -120.0}, (120.0, -1)),
        (MavCmd.NAV_LOITER_TIME, {"param3": 0.5}, (80.0, 1)),  # below 1 m: the default
        (MavCmd.NAV_LOITER_TIME, {"param3": math.nan}, (80.0, 1)),
        (MavCmd.NAV_LOITER_TO_ALT, {"param2": -90.0, "param3": 500.0}, (90.0, -1)),
    ],
)
def test_loiter_radius_and_direction(
    command: int, params: dict[str, float], expected: tuple[float, int]
) -> None:
    assert loiter_geometry(_item(command, **params), 80.0) == expected


def test_first_flown_item_follows_the_takeoff() -> None:
    items = (
        _item(MavCmd.NAV_WAYPOINT),
        _item(MavCmd.NAV_TAKEOFF),
        _item(MavCmd.DO_CHANGE_SPEED),
        _item(MavCmd.NAV_LOITER_UNLIM),
    )
    assert first_flown_item(Mission(items=items)) == 3
    assert first_flown_item(Mission(items=items[:1])) == 0  # no take-off: from the start
    assert first_flown_item(Mission(items=items[1:3])) == -1


def test_next_nav_index_counts_jumps_on_the_jump_item() -> None:
    items = (
        _item(MavCmd.NAV_WAYPOINT),
        _item(MavCmd.DO_CHANGE_SPEED),
        _jump(0, 2),
        _item(MavCmd.NAV_LAND),
    )
    counts: dict[int, int] = {}
    assert [next_nav_index(items, 1, counts) for _ in range(3)] == [0, 0, 3]
    assert counts == {2: 2}
    assert next_nav_index(items, 4, counts) == -1


def test_next_nav_index_ends_a_loop_without_navigation_items() -> None:
    items = (_item(MavCmd.NAV_WAYPOINT), _jump(2, MAX_DO_STEPS * 2), _jump(1, MAX_DO_STEPS * 2))
    assert next_nav_index(items, 1, {}) == -1


def test_params_are_what_from_params_takes() -> None:
    item = LOITER_TURNS
    back = MissionItem.from_params(item.command, item.frame, item.params, autocontinue=True, seq=3)
    assert repr(back) == repr(item)
