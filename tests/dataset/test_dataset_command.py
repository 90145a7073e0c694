"""``air-sitl dataset``: scenarios from a missions folder, in parallel, stats.csv, zips."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.check import check_archive
from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import write_plan
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def write_plan_file(path: Path, leg_m: float, alt_m: float) -> None:
    """Take-off, waypoint, IMAGE_START, a leg north, IMAGE_STOP, one more waypoint."""

    def wp(n: float, e: float) -> MissionItem:
        lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        return MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=lat, lon_deg=lon, alt_m=alt_m)

    items = (
        MissionItem(
            command=MavCmd.NAV_TAKEOFF,
            param1=15.0,
            lat_deg=HOME.lat_deg,
            lon_deg=HOME.lon_deg,
            alt_m=alt_m,
        ),
        wp(0.0, 300.0),
        MissionItem(command=MavCmd.IMAGE_START_CAPTURE, frame=MavFrame.MISSION, param2=0.02),
        wp(leg_m, 300.0),
        MissionItem(command=MavCmd.IMAGE_STOP_CAPTURE, frame=MavFrame.MISSION),
        wp(leg_m + 60.0, 300.0),
    )
    write_plan(Mission(items=items, planned_home=HOME, name=path.stem), path)


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_plan_file(folder / "UC-200.plan", 60.0, 200.0)
    write_plan_file(folder / "FC-300.plan", 90.0, 300.0)
    return folder


def test_two_scenarios_in_parallel_with_zips_and_the_air_table(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "root"
    argv = ["dataset", "--missions", str(missions), "--scenarios", "uc-200,FC-300"]
    argv += ["-j", "2", "--zip", "--air-start", "--out", str(root)]
    assert main(argv) == 0
    out = capsys.readouterr()
    assert "UC-200" in out.out and "total" in out.out
    assert "[2/2]" in out.err  # one progress line per scenario when not on a terminal
    with (root / "stats.csv").open(newline="") as f:
        rows = {r["scenario"]: r for r in csv.DictReader(f)}
    for name in ("UC-200", "FC-300"):
        manifest = json.loads((root / name / "manifest.json").read_text())
        assert int(rows[name]["images"]) == manifest["frame_count"] > 100
        assert rows[name]["paper_images"] in ("3422", "3450")
        assert float(rows[name]["images_ratio"]) == pytest.approx(
            manifest["frame_count"] / int(rows[name]["paper_images"]), abs=1e-3
        )
        assert manifest["map"]["kind"] == ("urban" if name.startswith("U") else "forest")
        with air_sitl.dataset.open(root / f"{name}.zip") as archive:
            report = check_archive(archive)
        assert report.valid and report.status == "complete", report.text()
    assert int(rows["total"]["images"]) == sum(int(rows[n]["images"]) for n in ("UC-200", "FC-300"))
    # --resume skips finished scenarios; without it the full folders are refused.
    assert main([*argv[:-2], "--out", str(root), "--resume"]) == 0
    assert main(argv) == 2
    assert "is not empty" in capsys.readouterr().err


def test_unknown_scenario_and_missing_missions_are_one_line_errors(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["dataset", "--missions", str(missions), "--scenarios", "XX-1"]) == 2
    err = capsys.readouterr().err.strip()
    assert "XX-1 has no plan" in err and "\n" not in err
    assert main(["dataset", "--missions", str(tmp_path / "none")]) == 2
    assert "--missions" in capsys.readouterr().err
