"""check_item / check_mission: the MAV_MISSION_RESULT each refusal maps to."""

from __future__ import annotations

import dataclasses
import math

import pytest

from air_sitl.mission.items import MavCmd, MavFrame, MissionItem, MissionResult, MissionType
from air_sitl.mission.validate import (
    ItemProblem,
    check_item,
    check_mission,
)

WP = MissionItem(
    command=MavCmd.NAV_WAYPOINT,
    frame=MavFrame.GLOBAL_RELATIVE_ALT_INT,
    param4=math.nan,
    lat_deg=54.687,
    lon_deg=25.279,
    alt_m=200.0,
)
SPEED = MissionItem(
    command=MavCmd.DO_CHANGE_SPEED, frame=MavFrame.MISSION, param1=1.0, param2=15.0, param3=-1
)
JUMP = MissionItem(command=MavCmd.DO_JUMP, frame=MavFrame.MISSION, param1=0.0, param2=2.0)
VERTEX = MissionItem(
    command=MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    frame=MavFrame.GLOBAL_INT,
    param1=3.0,
    lat_deg=54.6,
    lon_deg=25.2,
)
M = MissionType.MISSION
RALLY = MissionItem(command=MavCmd.NAV_RALLY_POINT, lat_deg=54.6, lon_deg=25.2, alt_m=50.0)


def change(item: MissionItem, **fields: float) -> MissionItem:
    return dataclasses.replace(item, **fields)  # type: ignore[arg-type]


def test_valid_items_pass() -> None:
    for item in (WP, SPEED, change(JUMP, param2=0.0)):
        assert check_item(item, 0, MissionType.MISSION) is None
    assert check_item(VERTEX, 0, MissionType.FENCE) is None
    assert check_item(change(VERTEX, alt_m=math.nan), 0, MissionType.FENCE) is None  # 2-D
    assert check_item(RALLY, 0, MissionType.RALLY) is None
    rtl = MissionItem(command=MavCmd.NAV_RETURN_TO_LAUNCH, frame=MavFrame.MISSION)
    assert check_item(rtl, 0, MissionType.MISSION) is None
    loiter = MissionItem(
        command=MavCmd.NAV_LOITER_TURNS,
        param1=1.0,
        param3=160.0,
        lat_deg=1.0,
        lon_deg=2.0,
        alt_m=300,
    )
    assert check_item(loiter, 0, MissionType.MISSION) is None


@pytest.mark.parametrize(
    ("item", "mission_type", "result", "value"),
    [
        (change(WP, frame=MavFrame.GLOBAL_TERRAIN_ALT), M, "UNSUPPORTED_FRAME", "TERRAIN"),
        (change(WP, frame=MavFrame.GLOBAL_TERRAIN_ALT_INT), M, "UNSUPPORTED_FRAME", "TERRAIN"),
        (change(WP, frame=1), M, "UNSUPPORTED_FRAME", "(1)"),  # LOCAL_NED
        (change(WP, frame=MavFrame.MISSION), M, "UNSUPPORTED_FRAME", "(MISSION)"),
        (change(SPEED, frame=4), M, "UNSUPPORTED_FRAME", "(4)"),
        (change(WP, command=9999), M, "UNSUPPORTED", "(9999)"),
        (change(WP, command=MavCmd.DO_SET_HOME), M, "UNSUPPORTED", "(179)"),
        (WP, MissionType.FENCE, "UNSUPPORTED", "(16)"),  # a waypoint in the fence list
        (VERTEX, MissionType.MISSION, "UNSUPPORTED", "(5001)"),
        (VERTEX, MissionType.RALLY, "UNSUPPORTED", "(5001)"),
        (change(WP, lat_deg=90.5), M, "INVALID_PARAM5_X", "(90.5)"),
        (change(WP, lat_deg=math.nan), M, "INVALID_PARAM5_X", "(nan)"),
        (change(WP, lon_deg=-180.25), M, "INVALID_PARAM6_Y", "(-180.25)"),
        (change(WP, alt_m=math.nan), M, "INVALID_PARAM7", "(nan)"),
        (change(WP, alt_m=math.inf), M, "INVALID_PARAM7", "(inf)"),
        (change(WP, param2=math.inf), M, "INVALID_PARAM2", "(inf)"),
        (change(SPEED, param1=7.0), M, "INVALID_PARAM1", "(7.0)"),
        (change(SPEED, param2=0.0), M, "INVALID_PARAM2", "(0.0)"),
        (change(JUMP, param1=-1.0), M, "INVALID_SEQUENCE", "(-1.0)"),
        (change(JUMP, param1=1.5), M, "INVALID_SEQUENCE", "(1.5)"),
        (change(JUMP, param2=-1.0), M, "INVALID_PARAM2", "(-1.0)"),
        (change(VERTEX, param1=2.0), MissionType.FENCE, "INVALID_PARAM1", "(2.0)"),
        (change(VERTEX, lon_deg=200.0), MissionType.FENCE, "INVALID_PARAM6_Y", "(200.0)"),
        (change(RALLY, lat_deg=-91.0), MissionType.RALLY, "INVALID_PARAM5_X", "(-91.0)"),
    ],
)
def test_item_problems(
    item: MissionItem, mission_type: MissionType, result: str, value: str
) -> None:
    problem = check_item(item, 7, mission_type)
    assert problem is not None
    assert problem.index == 7
    assert problem.result == f"MAV_MISSION_{result}"
    assert problem.message.endswith(")")
    assert value in problem.message, problem.message


def test_result_codes_follow_mavlink() -> None:
    # Spot checks against common.xml MAV_MISSION_RESULT.
    assert MissionResult.UNSUPPORTED_FRAME == 2
    assert MissionResult.INVALID_PARAM5_X == 10
    assert MissionResult.INVALID_SEQUENCE == 13
    problem = ItemProblem(index=0, result="MAV_MISSION_INVALID_PARAM7", message="x")
    assert problem.result_code == 12


def test_mission_checks_every_item_then_jumps() -> None:
    items = [WP, SPEED, change(WP, lat_deg=100.0), JUMP]
    problem = check_mission(items, MissionType.MISSION)
    assert problem is not None
    assert (problem.index, problem.result) == (2, "MAV_MISSION_INVALID_PARAM5_X")

    assert check_mission([WP, SPEED, JUMP], MissionType.MISSION) is None
    problem = check_mission([WP, SPEED, change(JUMP, param1=3.0)], MissionType.MISSION)
    assert problem is not None
    assert (problem.index, problem.result) == (2, "MAV_MISSION_INVALID_SEQUENCE")
    assert "(3)" in problem.message
    problem = check_mission([WP, SPEED, change(JUMP, param1=2.0)], MissionType.MISSION)
    assert problem is not None
    assert "itself" in problem.message


def test_empty_mission() -> None:
    problem = check_mission([], MissionType.MISSION)
    assert problem is not None
    assert (problem.index, problem.result) == (-1, "MAV_MISSION_INVALID")
    assert check_mission([], MissionType.MISSION, allow_empty=True) is None
    # a list with items but no navigation item is refused even when empty lists are allowed
    problem = check_mission([SPEED], MissionType.MISSION, allow_empty=True)
    assert problem is not None
    assert "(1 items)" in problem.message
    assert check_mission([], MissionType.FENCE) is None
    assert check_mission([], MissionType.RALLY) is None


def test_fence_polygons_must_be_complete_runs() -> None:
    triangle = [VERTEX, VERTEX, VERTEX]
    assert check_mission(triangle, MissionType.FENCE) is None
    problem = check_mission(triangle[:2], MissionType.FENCE)
    assert problem is not None
    assert (problem.index, problem.result) == (1, "MAV_MISSION_INVALID_PARAM1")
    mixed = [VERTEX, VERTEX, change(VERTEX, command=MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION)]
    problem = check_mission(mixed, MissionType.FENCE)
    assert problem is not None
    assert problem.index == 2
    circle = MissionItem(
        command=MavCmd.NAV_FENCE_CIRCLE_EXCLUSION, param1=100.0, lat_deg=54.6, lon_deg=25.2
    )
    assert check_mission([*triangle, circle, *triangle], MissionType.FENCE) is None
