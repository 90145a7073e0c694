"""Several map dates of one scenario fly once (issue 34): each date's archive is rendered from
the same flight's samples, and its bytes are those of flying that date alone."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
from short_plans import write_short_plan

from air_sitl.builder import FlightSetup, load_setup
from air_sitl.camera.model import CameraModel
from air_sitl.cli import main
from air_sitl.options import FlightOptions, MapChoice
from air_sitl.recording.batch import Job, date_groups
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def _files(folder: Path) -> dict[str, str]:
    files: dict[str, str] = json.loads((folder / "manifest.json").read_text())["files"]
    files.pop("summary.json")  # its wall time differs from flight to flight
    return files


def _summary(folder: Path) -> dict[str, object]:
    summary: dict[str, object] = json.loads((folder / "summary.json").read_text())
    for key in ("wall_time_s", "realtime_factor"):
        summary.pop(key)
    return summary


# The onboard filter's trajectory.csv has columns of its own; effects render by another path.
@pytest.mark.parametrize(
    "extra", [[], ["--nav", "ekf", "--camera-effects", "blur,vignette"]], ids=["truth", "ekf"]
)
def test_dates_flown_once_give_the_archives_of_flying_each_date(
    tmp_path: Path, extra: list[str]
) -> None:
    missions = tmp_path / "missions"
    missions.mkdir()
    write_short_plan(missions / "UC-200.plan", HOME, leg_m=40.0, alt_m=200.0, leg="north")
    base = ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--air-start"]
    base += ["--quiet", *extra]
    assert main([*base, "--dates", "0,2", "--out", str(tmp_path / "once")]) == 0
    for date in ("0", "2"):
        alone = tmp_path / f"alone{date}"
        assert main([*base, "--dates", date, "--out", str(alone)]) == 0
        once = tmp_path / "once" / f"UC-200@{date}"
        assert _files(once) == _files(alone / "UC-200"), date
        assert _summary(once) == _summary(alone / "UC-200"), date
    a, b = (_files(tmp_path / "once" / f"UC-200@{d}") for d in ("0", "2"))
    assert a["imu.csv"] == b["imu.csv"] and a["frame_000010.jpg"] != b["frame_000010.jpg"]


def test_only_dates_of_one_scenario_share_a_flight(tmp_path: Path) -> None:
    plan = write_short_plan(tmp_path / "UC-200.plan", HOME, leg_m=40.0)
    other = write_short_plan(tmp_path / "FC-300.plan", HOME, leg_m=40.0, alt_m=300.0)
    a = load_setup(plan, FlightOptions(), camera=CameraModel(), name="UC-200")
    b = load_setup(other, FlightOptions(), camera=CameraModel(), name="FC-300")

    def job(setup: FlightSetup, date: str) -> Job:
        out = tmp_path / f"{setup.name}@{date}"
        return Job(name=out.name, setup=replace(setup, map=MapChoice(date=date)), out=out,
                   resume=False, zip=False)  # fmt: skip

    groups = date_groups([job(a, "0"), job(b, "0"), job(a, "1")])
    assert [[j.name for j in g] for g in groups] == [["UC-200@0", "UC-200@1"], ["FC-300@0"]]
