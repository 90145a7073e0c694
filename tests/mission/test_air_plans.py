"""The scenario plans (AIR's 12 and the 6 farmland ones): they load, they are reproducible,
their geometry fits the paper (farmland: the figures of their urban counterparts)."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from air_sitl.dataset.scenarios import SCENARIO_TABLE
from air_sitl.frames import geodetic2ned
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import load_mission

REPO = Path(__file__).resolve().parents[2]
MISSIONS = REPO / "missions"
PAPER = SCENARIO_TABLE  # AIR paper, Table 2 and ours: (images at 50 Hz, captured distance m)
NAMES = sorted(PAPER)


def _ne(mission: Mission, item: MissionItem) -> tuple[float, float]:
    home = mission.planned_home
    assert home is not None
    n, e, _ = geodetic2ned(item.lat_deg, item.lon_deg, 0.0, home.lat_deg, home.lon_deg, 0.0)
    return (n, e)


def _index(mission: Mission, command: MavCmd) -> int:
    return next(i for i, it in enumerate(mission.items) if it.command == command)


def _start_point(mission: Mission) -> tuple[int, tuple[float, float]]:
    """Index of IMAGE_START_CAPTURE and the position of the nav item just before it (S)."""
    start = _index(mission, MavCmd.IMAGE_START_CAPTURE)
    s_item = next(it for it in reversed(mission.items[:start]) if it.is_nav)
    return start, _ne(mission, s_item)


def capture_length_m(mission: Mission) -> float:
    """Planned path length from S through the items up to IMAGE_STOP_CAPTURE."""
    start, pos = _start_point(mission)
    stop = _index(mission, MavCmd.IMAGE_STOP_CAPTURE)
    length = 0.0
    for item in mission.items[start + 1 : stop]:
        if item.command == MavCmd.NAV_WAYPOINT:
            nxt = _ne(mission, item)
            length += math.dist(pos, nxt)
            pos = nxt
        elif item.command == MavCmd.NAV_LOITER_TURNS:
            centre = _ne(mission, item)
            radius = abs(item.param3)
            to_circle = abs(math.dist(pos, centre) - radius)
            length += to_circle + item.param1 * 2.0 * math.pi * radius
        else:
            assert not item.is_nav, f"unexpected navigation item {item.command} in the capture"
    return length


@pytest.fixture(scope="module")
def plans() -> dict[str, Mission]:
    return {name: load_mission(MISSIONS / f"{name}.plan") for name in NAMES}


def test_the_plans_exist_and_validate(plans: dict[str, Mission]) -> None:
    assert sorted(p.stem for p in MISSIONS.glob("*.plan")) == NAMES
    for name, mission in plans.items():
        assert mission.name == name


def test_generator_reproduces_the_plans_and_the_readme_table(tmp_path: Path) -> None:
    result = subprocess.run(
        [sys.executable, str(MISSIONS / "make_air_plans.py"), "--out", str(tmp_path), "--table"],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    for name in NAMES:
        generated = (tmp_path / f"{name}.plan").read_bytes()
        assert generated == (MISSIONS / f"{name}.plan").read_bytes(), name
    table = result.stdout.strip()
    assert table.count("\n") == len(NAMES) + 1
    assert table in (MISSIONS / "README.md").read_text(encoding="utf-8")


@pytest.mark.parametrize("name", NAMES)
def test_capture_length_matches_the_paper(plans: dict[str, Mission], name: str) -> None:
    mission = plans[name]
    _images, distance = PAPER[name]
    length = capture_length_m(mission)
    assert abs(length - distance) / distance < 0.03, (length, distance)
    speed = mission.cruise_speed_m_s
    if name[1] == "R":
        # Planned perimeter = paper distance + what the aircraft cuts at 4 corners
        # (turn radius at 30 degrees of bank; a 90 degree arc is (2 - pi/2) r shorter).
        r = speed**2 / (9.80665 * math.tan(math.radians(30)))
        flown = length - 4 * (2 - math.pi / 2) * r
        assert abs(flown - distance) < 0.005 * distance, (flown, distance)
    else:
        assert abs(length - distance) < 0.001 * distance, (length, distance)


@pytest.mark.parametrize("name", NAMES)
def test_speed_is_the_papers_ground_speed(plans: dict[str, Mission], name: str) -> None:
    mission = plans[name]
    images, distance = PAPER[name]
    paper_speed = distance / (images / 50.0)
    speed_item = mission.items[_index(mission, MavCmd.DO_CHANGE_SPEED)]
    assert speed_item.param2 == mission.cruise_speed_m_s
    assert abs(speed_item.param2 - paper_speed) < 0.01
    assert speed_item.param1 == 1.0  # ground speed
    # the DO_CHANGE_SPEED acts before the run-in
    assert _index(mission, MavCmd.DO_CHANGE_SPEED) < _index(mission, MavCmd.IMAGE_START_CAPTURE)
    if name == "FL-200":
        assert speed_item.param2 == pytest.approx(12.4, abs=0.05)
    else:
        assert speed_item.param2 == pytest.approx(15.0, abs=0.3)


@pytest.mark.parametrize("name", NAMES)
def test_mission_structure(plans: dict[str, Mission], name: str) -> None:
    mission = plans[name]
    alt = float(name.split("-")[1])
    items = mission.items
    assert items[0].command == MavCmd.NAV_TAKEOFF
    assert items[-1].command == MavCmd.NAV_RETURN_TO_LAUNCH
    for item in items:
        if item.is_nav and item.command != MavCmd.NAV_RETURN_TO_LAUNCH:
            assert item.frame == MavFrame.GLOBAL_RELATIVE_ALT
            assert item.alt_m == alt
    start = items[_index(mission, MavCmd.IMAGE_START_CAPTURE)]
    assert start.param2 == 0.02
    assert _index(mission, MavCmd.IMAGE_STOP_CAPTURE) == len(items) - 2


@pytest.mark.parametrize("name", NAMES)
def test_run_in_is_lined_up_with_the_first_leg(plans: dict[str, Mission], name: str) -> None:
    mission = plans[name]
    start, s = _start_point(mission)
    navs = [it for it in mission.items[:start] if it.is_nav]
    run_in_from = _ne(mission, navs[-2])
    assert math.dist(run_in_from, s) >= 300.0
    run_in = math.atan2(s[1] - run_in_from[1], s[0] - run_in_from[0])
    first = next(it for it in mission.items[start + 1 :] if it.is_nav)
    if first.command == MavCmd.NAV_LOITER_TURNS:
        centre = _ne(mission, first)
        assert first.param1 == 1.0
        assert first.param3 > 0  # clockwise
        assert math.dist(centre, s) == pytest.approx(first.param3, abs=0.5)  # S on the circle
        u = ((s[0] - centre[0]) / first.param3, (s[1] - centre[1]) / first.param3)
        leg = math.atan2(u[0], -u[1])  # clockwise tangent at S: (-u_e, u_n) as (n, e)
    else:
        nxt = _ne(mission, first)
        leg = math.atan2(nxt[1] - s[1], nxt[0] - s[0])
    assert abs(math.remainder(leg - run_in, 2 * math.pi)) < math.radians(0.5)


@pytest.mark.parametrize("name", [n for n in NAMES if n[1] == "R"])
def test_rectangles_close_at_the_start_point(plans: dict[str, Mission], name: str) -> None:
    mission = plans[name]
    start, s = _start_point(mission)
    stop = _index(mission, MavCmd.IMAGE_STOP_CAPTURE)
    corners = [_ne(mission, it) for it in mission.items[start + 1 : stop]]
    assert len(corners) == 5
    assert math.dist(corners[-1], s) < 0.5
    # four right angles, all turning the same way (clockwise: right turns)
    pts = [s, *corners]
    for a, b, c in zip(pts, pts[1:], pts[2:], strict=False):
        h1 = math.atan2(b[1] - a[1], b[0] - a[0])
        h2 = math.atan2(c[1] - b[1], c[0] - b[0])
        turn = math.degrees(math.remainder(h2 - h1, 2 * math.pi))
        assert turn == pytest.approx(90.0, abs=0.5)
