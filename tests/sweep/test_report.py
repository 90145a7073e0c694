"""``sweep report`` on rows written by hand: what the table and the figure say."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from air_sitl.cli import main
from air_sitl.sweep.results import RESULTS


def _report(horizontal: float, recall: float) -> dict[str, object]:
    return {
        "horizontal_error_m": {"median": horizontal, "p95": 2.0 * horizontal},
        "recall": {"5m": recall / 2, "25m": recall},
        "availability": 1.0,
        "drift_pct": 0.1 * horizontal,
    }


def _sweep(tmp_path: Path, recalls: list[float]) -> Path:
    rows = []
    for k, recall in enumerate(recalls):
        options = {"map-date": k % 2, "seed": k // 2}
        rows.append(
            {
                "id": f"run{k}",
                "options": options,
                "summary": {"capture_frames": 100},
                "eval": {"mapmatch": _report(1.0 + k, recall), "vo": _report(3.0 + k, recall)},
                "error": None,
                "wall_s": 1.0,
                "host": "here",
            }
        )
    tmp_path.mkdir()
    (tmp_path / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    (tmp_path / "sweep.json").write_text(json.dumps({"axes": ["map-date", "seed"]}))
    return tmp_path


def _png_height(png: bytes) -> int:
    assert png.startswith(b"\x89PNG")
    return int.from_bytes(png[20:24], "big")


def test_a_metric_the_same_in_every_run_is_named_not_drawn(tmp_path: Path) -> None:
    flat = _sweep(tmp_path / "flat", [1.0, 1.0, 1.0, 1.0])
    varied = _sweep(tmp_path / "varied", [1.0, 0.8, 0.9, 0.7])
    for folder in (flat, varied):
        assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    flat_md = (flat / "report.md").read_text()
    varied_md = (varied / "report.md").read_text()
    same = "The same in every run: recall at 5 m 0.50, recall at 25 m 1.00, availability 1.00"
    assert same in flat_md
    assert "The same in every run: availability 1.00" in varied_md
    # The tables keep every column either way.
    row = "| 0 | mapmatch | 2 | 0 | 2.00 (1.50-2.50) | 4.00 | 0.50 | 1.00 | 1.00 | - | - | 0.2 |"
    assert row in flat_md
    # One row of panels fewer for the one more constant metric.
    flat_h = _png_height((flat / "report.png").read_bytes())
    varied_h = _png_height((varied / "report.png").read_bytes())
    assert flat_h < varied_h


def test_the_fix_rate_per_date_gap_beside_availability(tmp_path: Path) -> None:
    """Rows carry each method's fix_rate and longest_without_fix_s (its eval report): the
    report shows them per map date; a method without map fixes shows '-'."""
    folder = _sweep(tmp_path / "fixes", [1.0, 0.8, 0.9, 0.7])
    rows = [json.loads(line) for line in (folder / RESULTS).read_text().splitlines()]
    for row in rows:
        gap = row["options"]["map-date"]
        row["eval"]["mapmatch"].update(fix_rate=1.0 - 0.6 * gap, longest_without_fix_s=5.0 * gap)
        row["eval"]["vo"].update(fix_rate=None, longest_without_fix_s=None)
    (folder / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    md = (folder / "report.md").read_text()
    head = md.split("## map-date", 1)[1].split("\n")[2]
    assert "| availability | fix rate | longest without fix s |" in head
    assert (
        "| 1 | mapmatch | 2 | 0 | 3.00 (2.50-3.50) | 6.00 | 0.38 | 0.75 | 1.00 | 0.40 | 5.0 |" in md
    )
    assert "| 1 | vo | 2 | 0 | 5.00 (4.50-5.50) | 10.00 | 0.38 | 0.75 | 1.00 | - | - |" in md


def test_a_partial_sweep_says_how_many_runs_and_which_axes_it_left_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _sweep(tmp_path / "partial", [1.0, 0.8, 0.9, 0.7])
    # The SPEC planned 6 runs over three axes; 4 ran, all at one wind.
    rows = [json.loads(line) for line in (folder / RESULTS).read_text().splitlines()]
    for row in rows:
        row["options"]["wind"] = "5@270"
    (folder / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    info = {"axes": ["map-date", "wind", "seed"], "runs": [f"run{k}" for k in range(6)]}
    (folder / "sweep.json").write_text(json.dumps(info))
    assert main(["sweep", "report", str(folder)]) == 0
    err = capsys.readouterr().err
    assert "sweep report: partial sweep: 4 of 6 planned runs have results (2 not run yet)" in err
    assert "sweep report: axis wind left out: one value among these runs (5@270)" in err
    md = (folder / "report.md").read_text()
    assert "- partial sweep: 4 of 6 planned runs have results (2 not run yet)" in md
    assert "## wind" not in md


def test_a_complete_sweep_has_no_coverage_notes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = _sweep(tmp_path / "whole", [1.0, 0.8, 0.9, 0.7])
    info = {"axes": ["map-date", "seed"], "runs": [f"run{k}" for k in range(4)]}
    (folder / "sweep.json").write_text(json.dumps(info))
    assert main(["sweep", "report", str(folder)]) == 0
    assert "sweep report:" not in capsys.readouterr().err


def test_the_report_names_reference_and_flight_dates(tmp_path: Path) -> None:
    """Flights over date 0 match date 1 by default, the others date 0; a bench's rows say
    their reference date."""
    folder = _sweep(tmp_path / "dates", [1.0, 0.8, 0.9, 0.7])
    assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    md = (folder / "report.md").read_text()
    assert (
        "Map dates (map-based methods): reference date 0 -> flight date 1 (2 runs), "
        "reference date 1 -> flight date 0 (2 runs)." in md
    )
    rows = [json.loads(line) for line in (folder / RESULTS).read_text().splitlines()]
    for row in rows:
        row["reference_date"] = 2
    (folder / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    md = (folder / "report.md").read_text()
    assert "reference date 2 -> flight date 0 (2 runs), reference date 2 -> flight date 1" in md


def test_the_report_names_the_dates_the_runs_flew(tmp_path: Path) -> None:
    """Runs whose summary.json names their map's dates (a GeoTIFF folder's acquisitions, by
    --map-date given as a date) are grouped by index and named by date."""
    folder = _sweep(tmp_path / "real", [1.0, 0.8, 0.9, 0.7])
    dates = ["2010-06-14", "2014-07-02", "2018-08-20"]
    rows = [json.loads(line) for line in (folder / RESULTS).read_text().splitlines()]
    for row in rows:
        row["options"]["map-date"] = "2018-08-20"
        row["summary"] = {**(row.get("summary") or {}), "map": {"date_index": 2, "dates": dates}}
        row["reference_date"] = 0
    (folder / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    md = (folder / "report.md").read_text()
    assert "reference date 0 (2010-06-14) -> flight date 2 (2018-08-20) (4 runs)" in md


def test_worlds_with_their_own_calendars_are_named_each() -> None:
    """A sweep over urban and farmland scenarios: one gap, each world's dates named."""
    from air_sitl.sweep.report import date_gaps

    urban = {"date_index": 1, "dates": ["2009-06-20", "2012-10-08", "2016-04-22"]}
    farm = {"date_index": 1, "dates": ["2009-06-20", "2012-07-24", "2016-08-13"]}
    rows = [{"summary": {"map": block}, "options": {}} for block in (urban, farm, urban)]
    assert date_gaps(rows) == (
        "Map dates (map-based methods): reference date 0 (2009-06-20) -> flight date 1 "
        "(2012-10-08) / reference date 0 (2009-06-20) -> flight date 1 (2012-07-24) (3 runs)."
    )


def test_the_time_table_sums_each_part_over_the_runs(tmp_path: Path) -> None:
    folder = _sweep(tmp_path / "timed", [1.0, 0.8, 0.9, 0.7])
    rows = [json.loads(line) for line in (folder / RESULTS).read_text().splitlines()]
    for k, row in enumerate(rows):  # a run's share of a flight, its own date, its methods
        row["time_s"] = {"fly": 2.0, "render": 1.0 + k, "localize": 3.0, "eval": 0.5}
    (folder / RESULTS).write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert main(["sweep", "report", str(folder), "--quiet"]) == 0
    md = (folder / "report.md").read_text()
    assert "## Where the time went" in md and "4 runs, 32 s of run time in all" in md
    assert "| fly | 8.0 | 25% | 2.00 |" in md
    assert "| render | 10.0 | 31% | 2.50 |" in md
    assert "| localize | 12.0 | 38% | 3.00 |" in md
    assert "| eval | 2.0 | 6% | 0.50 |" in md
