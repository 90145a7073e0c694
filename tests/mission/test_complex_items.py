"""QGroundControl complex items: the mission items QGC generated and saved in the plan are
flown (a survey's camera trigger items open and close the capture window); a complex item
saved without them is refused in one line naming it. A plan for another vehicle type warns."""

from __future__ import annotations

import copy
import json
from pathlib import Path
from typing import Any

import pytest

from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.tasks import NavOutput
from air_sitl.errors import PlanError
from air_sitl.mission.items import MavCmd
from air_sitl.mission.plan_file import load_mission
from air_sitl.mission.validate import mission_warnings
from air_sitl.state import VehicleState
from tests.autopilot.sim import HOME, air_started, run

SURVEY = Path(__file__).parent / "plans" / "survey.plan"


def _doc() -> dict[str, Any]:
    doc: dict[str, Any] = json.loads(SURVEY.read_text())
    return doc


def _write(tmp_path: Path, doc: dict[str, Any], name: str = "p.plan") -> Path:
    path = tmp_path / name
    path.write_text(json.dumps(doc))
    return path


def test_survey_plan_flies_its_generated_items() -> None:
    doc = _doc()
    generated = doc["mission"]["items"][1]["TransectStyleComplexItem"]["Items"]
    m = load_mission(SURVEY)
    assert (m.planned_home.lat_deg, m.planned_home.lon_deg) == (HOME.lat_deg, HOME.lon_deg)  # type: ignore[union-attr]
    assert len(m.items) == 1 + len(generated) + 1
    assert [i.command for i in m.items[1:-1]] == [g["command"] for g in generated]
    assert m.items[0].command == MavCmd.NAV_TAKEOFF
    assert m.items[-1].command == MavCmd.NAV_RETURN_TO_LAUNCH
    assert mission_warnings(m) == []


def test_survey_trigger_items_bound_the_capture_window_to_the_transects() -> None:
    m = load_mission(SURVEY)
    ex, plane = air_started(m)
    captured: list[tuple[float, float]] = []

    def each(x: MissionExecutor, s: VehicleState, _o: NavOutput) -> None:
        if x.capturing:
            captured.append((s.pos_ned_m[0], s.pos_ned_m[1]))

    run(ex, plane, each=each, max_s=4000)
    assert ex.mission_completed
    # Independent truth: the survey polygon's transects are east = 200, 320, 440, 560 m,
    # north 300..1100 m (see how tests/mission/plans/survey.plan was made).
    lanes = {200.0: [], 320.0: [], 440.0: [], 560.0: []}  # type: dict[float, list[float]]
    for n, e in captured:
        lane = min(lanes, key=lambda x: abs(x - e))
        assert abs(e - lane) < 30.0, (n, e)  # never in a turn between transects
        assert 250.0 < n < 1150.0, (n, e)
        lanes[lane].append(n)
    for lane, norths in lanes.items():
        assert norths, lane
        assert min(norths) < 350.0 and max(norths) > 1050.0, lane  # the whole transect


def test_corridor_and_structure_scans_fly_their_items(tmp_path: Path) -> None:
    doc = _doc()
    survey = doc["mission"]["items"][1]
    corridor = copy.deepcopy(survey)
    corridor["complexItemType"] = "CorridorScan"
    structure = {
        "type": "ComplexItem",
        "complexItemType": "StructureScan",
        "version": 3,
        "Items": copy.deepcopy(survey["TransectStyleComplexItem"]["Items"][:6]),
        "polygon": survey["polygon"],
    }
    doc["mission"]["items"][1:2] = [corridor, structure]
    m = load_mission(_write(tmp_path, doc))
    assert len(m.items) == 1 + 24 + 6 + 1


def test_complex_item_without_generated_items_is_one_line_naming_it(tmp_path: Path) -> None:
    doc = _doc()
    doc["mission"]["items"].insert(
        2,
        {
            "type": "ComplexItem",
            "complexItemType": "fwLandingPattern",
            "landCoordinate": [54.68, 25.29, 0],
            "loiterCoordinate": [54.685, 25.29, 40],
            "version": 2,
        },
    )
    with pytest.raises(PlanError) as info:
        load_mission(_write(tmp_path, doc))
    text = str(info.value)
    assert "\n" not in text
    assert "item 2: QGroundControl fixed-wing landing pattern without the mission items" in text


def test_errors_inside_a_survey_name_the_generated_item(tmp_path: Path) -> None:
    doc = _doc()
    doc["mission"]["items"][1]["TransectStyleComplexItem"]["Items"][3]["frame"] = 11
    with pytest.raises(PlanError, match=r"item 1 \(survey, generated item 3\): terrain"):
        load_mission(_write(tmp_path, doc))


def test_do_jump_into_a_survey_uses_the_generated_jump_id(tmp_path: Path) -> None:
    doc = _doc()
    items = doc["mission"]["items"]
    items.insert(2, {"type": "SimpleItem", "command": 177, "frame": 2, "autoContinue": True,
                     "doJumpId": 27, "params": [3, 1, 0, 0, 0, 0, 0]})  # fmt: skip
    m = load_mission(_write(tmp_path, doc))
    # doJumpId 3 is the survey's second generated item: index 2 of the flat mission.
    assert m.items[25].command == MavCmd.DO_JUMP and m.items[25].param1 == 2.0


@pytest.mark.parametrize(("vehicle", "name"), [(2, "QUADROTOR"), (22, "VTOL_FIXEDROTOR")])
def test_a_plan_for_another_vehicle_type_warns(tmp_path: Path, vehicle: int, name: str) -> None:
    doc = _doc()
    doc["mission"]["vehicleType"] = vehicle
    m = load_mission(_write(tmp_path, doc))
    (warning,) = mission_warnings(m)
    assert f"vehicleType is {name} ({vehicle})" in warning and "fixed-wing" in warning
