"""``bench --map-date 0,1,2``: one leaderboard per date gap, and a summary across the gaps."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import short_plans
from cli_errors import one_line_error

from air_sitl.bench.leaderboard import build, gaps_json, gaps_markdown
from air_sitl.cli import main
from air_sitl.commands.bench import flight_dates
from air_sitl.errors import OptionError
from air_sitl.state import GeoPoint
from air_sitl.sweep.measurements import EntryResult


def _result(
    scenario: str, entry: str, median: float, recall: float, fixes: float | None = None
) -> EntryResult:
    report = {
        "horizontal_error_m": {"median": median, "rmse": median, "p95": 2 * median},
        "recall": {"5m": recall / 2, "25m": recall},
        "availability": 1.0,
        "fix_rate": fixes,
        "longest_without_fix_s": None if fixes is None else 10.0 * (1.0 - fixes),
    }
    return EntryResult(scenario=scenario, entry=entry, report=report)


def test_gaps_summary_and_one_section_per_gap() -> None:
    boards = [
        build(
            ("mapmatch", "vo"),
            ("UC-200", "FC-200"),
            [
                _result("UC-200", "mapmatch", 2.0 + 10 * d, 1.0 - 0.2 * d, 1.0 - 0.4 * d),
                _result("FC-200", "mapmatch", 4.0 + 10 * d, 1.0 - 0.3 * d, 1.0 - 0.5 * d),
                _result("UC-200", "vo", 30.0, 0.5),
                _result("FC-200", "vo", 40.0, 0.4),
            ],
            (0, d),
        )
        for d in (0, 1, 2)
    ]
    md = gaps_markdown(boards)
    assert "| method | 0 -> 0 | 0 -> 1 | 0 -> 2 |" in md
    assert "| mapmatch | 3.0 | 13.0 | 23.0 |" in md  # the median over the two scenarios
    assert "| mapmatch | 1.000 | 0.750 | 0.500 |" in md  # recall@25 m
    assert "| mapmatch | 0.500 | 0.375 | 0.250 |" in md  # recall@5 m: finer than 25 m
    assert "| mapmatch | 6.0 | 26.0 | 46.0 |" in md  # p95
    # availability stays 1 while the fix rate falls with the gap; vo has no map fixes
    fix_table = md.split("## fix rate", 1)[1].split("\n## ", 1)[0]
    assert "| mapmatch | 1.000 | 0.550 | 0.100 |" in fix_table
    assert "| vo | - | - | - |" in fix_table
    assert "| mapmatch | 0.0 | 4.5 | 9.0 |" in md.split("## longest time without", 1)[1]
    for d in (0, 1, 2):
        assert f"# reference date 0 -> flight date {d}" in md
    assert md.count("### median horizontal error (m)") == 3
    data = gaps_json(boards)
    assert [(g["reference_date"], g["flight_date"]) for g in data["gaps"]] == [
        (0, 0),
        (0, 1),
        (0, 2),
    ]
    assert "Map dates: reference date 0 -> flight date 2" in boards[2].to_markdown()
    assert data["gaps"][2]["summary"]["mapmatch"]["fix_rate"] == pytest.approx(0.1)
    assert data["gaps"][2]["summary"]["vo"]["fix_rate"] is None
    row = data["gaps"][1]["rows"][0]
    assert (row["method"], row["scenario"], row["availability"]) == ("mapmatch", "UC-200", 1.0)
    assert row["fix_rate"] == pytest.approx(0.6)
    assert row["longest_without_fix_s"] == pytest.approx(4.0)


def test_map_dates_parse_and_refuse_repeats(capsys: pytest.CaptureFixture[str]) -> None:
    assert flight_dates("1") == (1,)
    assert flight_dates("0,1,2") == (0, 1, 2)
    with pytest.raises(OptionError):
        flight_dates("0,2,2")
    argv = ["bench", "--scenarios", "UC-200", "--map-date", "0,2,2", "--out", "unused"]
    assert "--map-date 0,2,2: a date is given twice" in one_line_error(argv, capsys)


def test_a_bench_scores_the_three_date_gaps_by_default() -> None:
    """Without --map-date, flights over dates 0, 1 and 2 against the reference date 0."""
    from air_sitl.cli import build_parser

    args = build_parser().parse_args(["bench", "--scenarios", "UC-200", "--out", "unused"])
    assert flight_dates(args.map_date) == (0, 1, 2)
    assert int(args.reference_date) == 0


@pytest.mark.integration
def test_a_bench_over_two_dates_scores_each_gap(tmp_path: Path) -> None:
    """Real short flights over dates 0 and 2, mapmatch against date 0: a bench per date and
    the leaderboard by gap, each saying its reference and flight date; deadreckon scored
    once for both dates."""
    home = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)
    missions = tmp_path / "missions"
    missions.mkdir()
    short_plans.write_short_plan(missions / "UT-200.plan", home, leg_m=60.0)
    out = tmp_path / "b"
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "mapmatch,deadreckon", "--missions",
        str(missions), "--map-date", "0,2", "--out", str(out), "--quiet",
    ]  # fmt: skip
    assert main(argv) == 0
    data = json.loads((out / "leaderboard.json").read_text())
    gaps = [(g["reference_date"], g["flight_date"]) for g in data["gaps"]]
    assert gaps == [(0, 0), (0, 2)]
    for d in (0, 2):
        manifest = json.loads(
            (out / f"date{d}" / "archives" / "UT-200" / "manifest.json").read_text()
        )
        assert manifest["map"]["date_index"] == d
        assert (out / f"date{d}" / "leaderboard.md").is_file()
    # One flight for both dates (made under flights/, then moved): the same samples.
    assert (out / "flights").is_dir() and not list((out / "flights").glob("UT-200@*"))
    imu = {
        json.loads((out / f"date{d}" / "archives" / "UT-200" / "manifest.json").read_text())[
            "files"
        ]["imu.csv"]
        for d in (0, 2)
    }
    assert len(imu) == 1
    md = (out / "leaderboard.md").read_text()
    # The gaps by their surveys' dates (the procedural map's DATES)
    assert "| method | 2009-06-20 -> 2009-06-20 | 2009-06-20 -> 2016-04-22 |" in md
    assert "# reference date 0 (2009-06-20) -> flight date 2 (2016-04-22)" in md
    assert data["gaps"][1]["map_dates"] == ["2009-06-20", "2012-10-08", "2016-04-22"]
    medians = [g["summary"]["mapmatch"]["median_m"] for g in data["gaps"]]
    assert all(m is not None for m in medians)
    # deadreckon reads no imagery: localized and scored once for the flight, by the one
    # worker the dates' sweeps share; date 2 takes date 0's run (its timing too) and report.
    found = [
        json.loads((out / f"date{d}" / "reports" / "UT-200" / "deadreckon.json").read_text())
        for d in (0, 2)
    ]
    assert found[0]["localize_wall_s"] == found[1]["localize_wall_s"]
    assert found[0]["report"] == found[1]["report"]
    estimates = {
        (out / f"date{d}" / "archives" / "UT-200" / "estimates" / "deadreckon.csv").read_bytes()
        for d in (0, 2)
    }
    assert len(estimates) == 1


def test_scenarios_over_worlds_of_their_own_calendars_name_both_dates(tmp_path: Path) -> None:
    """AIR's urban scenarios and farmland's in one bench: an index's dates are joined."""
    from types import SimpleNamespace

    from air_sitl.bench import _map_dates
    from air_sitl.dataset.air_schema import MANIFEST_JSON

    for name, kind in (("UL-200", "urban"), ("AL-200", "farmland")):
        (tmp_path / name).mkdir()
        info = {"source": "procedural", "kind": kind, "date": "2009-06-20", "date_index": 0}
        (tmp_path / name / MANIFEST_JSON).write_text(json.dumps({"map": info}))
    config = SimpleNamespace(archives=tmp_path, scenarios=["UL-200", "AL-200"])
    assert _map_dates(config) == (  # type: ignore[arg-type]
        "2009-06-20",
        "2012-10-08 / 2012-07-24",
        "2016-04-22 / 2016-08-13",
    )
