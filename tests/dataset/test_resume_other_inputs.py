"""``--resume`` on a complete archive of other inputs refuses with one line naming what
differs (fly and dataset), and still says "nothing to do" for the same inputs."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from cli_errors import one_line_error
from short_plans import write_short_plan

from air_sitl.cli import main
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_short_plan(folder / "UC-200.plan", HOME, leg_m=20.0, leg="north")
    write_short_plan(folder / "UC-300.plan", HOME, leg_m=20.0, leg="north", alt_m=300.0)
    return folder


def test_fly_resume_refuses_a_complete_archive_of_another_plan(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "uc200"
    assert (
        main(["fly", str(missions / "UC-200.plan"), "--air-start", "--quiet", "--out", str(out)])
        == 0
    )
    before = {p.name: p.stat().st_mtime_ns for p in out.rglob("*")}
    again = ["fly", str(missions / "UC-200.plan"), "--air-start", "--resume", "--out", str(out)]
    assert main(again) == 0
    assert "already complete" in capsys.readouterr().out
    other = ["fly", str(missions / "UC-300.plan"), "--air-start", "--resume", "--out", str(out)]
    line = one_line_error(other, capsys)
    assert line == (
        f"air-sitl: error: {out}: --resume: a complete archive of other inputs (plan: archive "
        "UC-200, this run UC-300); --overwrite replaces it, or another --out"
    )
    options = [*again, "--wind", "5@270"]
    assert "(flight differs)" in one_line_error(options, capsys)
    assert "(map differs)" in one_line_error([*again, "--map-date", "2"], capsys)
    assert {p.name: p.stat().st_mtime_ns for p in out.rglob("*")} == before  # untouched


def test_dataset_resume_does_not_report_another_scenario_as_its_own(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "root"
    argv = ["dataset", "--missions", str(missions), "--air-start", "--quiet", "--out", str(root)]
    assert main([*argv, "--scenarios", "UC-200"]) == 0
    shutil.move(root / "UC-200", root / "UC-300")  # UC-200's archive where UC-300's goes
    (root / "stats.csv").unlink()
    capsys.readouterr()
    assert main([*argv, "--scenarios", "UC-300", "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "UC-300: " in err and "(plan: archive UC-200, this run UC-300)" in err
    manifest = json.loads((root / "UC-300" / "manifest.json").read_text())
    assert manifest["scenario"] == "UC-200"  # left as it was
    assert not (root / "stats.csv").exists()
