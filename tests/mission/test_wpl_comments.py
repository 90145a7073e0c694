"""QGC WPL files with ``#`` comment lines and blank lines read as QGC and MAVProxy read them."""

from __future__ import annotations

from pathlib import Path

import pytest

from air_sitl.errors import PlanError
from air_sitl.mission.plan_file import load_mission

PLAIN = (
    "QGC WPL 110\n"
    "0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.000000\t1\n"
    "1\t0\t3\t22\t15\t0\t0\t0\t47.398500\t8.545600\t100.000000\t1\n"
    "2\t0\t3\t16\t0\t0\t0\t0\t47.400500\t8.546000\t100.000000\t1\n"
    "3\t0\t2\t177\t2\t1\t0\t0\t0\t0\t0\t1\n"
    "4\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n"
)

COMMENTED = (
    "# survey of the north field, written by hand\n"
    "\n"
    "QGC WPL 110\n"
    "# home\n"
    "0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.000000\t1\n"
    "\n"
    "   # take-off, then the leg\n"
    "1\t0\t3\t22\t15\t0\t0\t0\t47.398500\t8.545600\t100.000000\t1\n"
    "2\t0\t3\t16\t0\t0\t0\t0\t47.400500\t8.546000\t100.000000\t1\n"
    "\r\n"
    "# jump back to seq 2 once\n"
    "3\t0\t2\t177\t2\t1\t0\t0\t0\t0\t0\t1\n"
    "4\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t1\n"
    "# end\n"
)


def test_comments_and_blank_lines_are_skipped(tmp_path: Path) -> None:
    plain = tmp_path / "plain.waypoints"
    plain.write_text(PLAIN)
    commented = tmp_path / "commented.waypoints"
    commented.write_text(COMMENTED)
    expected = load_mission(plain)
    got = load_mission(commented)
    assert got.items == expected.items
    assert got.planned_home == expected.planned_home
    assert [i.command for i in got.items] == [22, 16, 177, 20]
    assert got.items[2].param1 == 1.0  # DO_JUMP to WPL seq 2 = index 1, comments not counted


def test_errors_name_the_real_line_number(tmp_path: Path) -> None:
    path = tmp_path / "bad.waypoints"
    bad = COMMENTED.replace("47.400500\t8.546000", "47.400500\tabc")
    path.write_text(bad)
    line = 1 + bad.splitlines().index(next(x for x in bad.splitlines() if "abc" in x))
    with pytest.raises(PlanError, match=rf"line {line}: column y/longitude"):
        load_mission(path)


def test_a_comment_only_file_is_not_a_plan(tmp_path: Path) -> None:
    path = tmp_path / "empty.waypoints"
    path.write_text("# nothing here\n\n")
    with pytest.raises(PlanError):
        load_mission(path)
