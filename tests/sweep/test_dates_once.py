"""A sweep's map-date axis flies once (issue 34): runs that differ only in the map date are one
task, every date rendered from the same flight, and each archive and row is what flying that
date alone gives; runs whose flight may depend on the imagery are not grouped."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import pytest
import short_plans
import yaml

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from air_sitl.sweep import load_spec, make_tasks
from air_sitl.sweep.groups import group_tasks
from air_sitl.sweep.results import RESULTS, comparable, latest_rows

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)
DATES = (0, 1, 2)
WALL_CLOCK = ("wall_time_s", "realtime_factor")


def _spec(folder: Path, name: str, extra: dict[str, Any]) -> Path:
    content = {
        "base": {"plan": "plans/UT-200.plan", "air-start": True, "max-sim-time": 60},
        "methods": ["deadreckon"],
        "reference-date": 0,
        **extra,
    }
    path = folder / name
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("dates-once")
    (root / "plans").mkdir()
    short_plans.write_short_plan(root / "plans" / "UT-200.plan", HOME, leg_m=30.0)  # 100 frames
    return root


def _files(archive: Path) -> dict[str, str]:
    files: dict[str, str] = json.loads((archive / "manifest.json").read_text())["files"]
    files.pop("summary.json")  # its wall time differs from flight to flight
    return files


def _summary(archive: Path) -> dict[str, Any]:
    summary = json.loads((archive / "summary.json").read_text())
    return {k: v for k, v in summary.items() if k not in WALL_CLOCK}


@pytest.mark.integration
def test_a_map_date_axis_flies_once_and_each_date_is_its_flight_alone(folder: Path) -> None:
    spec = _spec(folder, "dates.yaml", {"axes": {"map-date": list(DATES)}})
    tasks = make_tasks(load_spec(spec), folder / "once")
    assert [len(g) for g in group_tasks(tasks)] == [3]  # one task flies the three dates
    assert main(["sweep", str(spec), "--out", str(folder / "once"), "--quiet"]) == 0
    once = latest_rows(folder / "once" / RESULTS)
    assert len(once) == len(DATES)
    for date in DATES:  # the same run as a sweep of its own: a group of one, flown alone
        alone = _spec(folder, f"alone{date}.yaml", {"axes": {"map-date": [date]}})
        assert main(["sweep", str(alone), "--out", str(folder / f"alone{date}"), "--quiet"]) == 0
        ((ident, row),) = latest_rows(folder / f"alone{date}" / RESULTS).items()
        assert comparable(once[ident]) == comparable(row), date  # the same id: the same options
        a, b = folder / "once" / "runs" / ident, folder / f"alone{date}" / "runs" / ident
        assert _files(a) == _files(b), date
        assert _summary(a) == _summary(b), date
        assert sorted(row["time_s"]) == sorted(once[ident]["time_s"])
        assert set(row["time_s"]) == {"fly", "render", "localize", "eval"}
        assert once[ident]["time_s"]["render"] > 0 and row["time_s"]["render"] > 0
    a, b = (_files(folder / "once" / "runs" / i) for i in sorted(once)[:2])
    assert a["imu.csv"] == b["imu.csv"] and a["frame_000010.jpg"] != b["frame_000010.jpg"]


def test_runs_whose_flight_may_depend_on_the_imagery_are_not_grouped(folder: Path) -> None:
    program = Path(__file__).resolve().parents[2] / "bridges" / "example_localizer.py"
    axes = {"axes": {"map-date": list(DATES), "seed": [1, 2]}}
    cases = {
        "plain": ({**axes}, [3, 3]),  # a group per seed, each of the three dates
        "lockstep": ({**axes, "localizers": {"ex": f"{sys.executable} {program}"}}, [1] * 6),
        "aid": ({**axes, "base": {"plan": "plans/UT-200.plan", "nav-aid": "vo"}}, [1] * 6),
        "bus": ({**axes, "base": {"plan": "plans/UT-200.plan", "zenoh": True}}, [1] * 6),
    }
    for name, (extra, sizes) in cases.items():
        spec = load_spec(_spec(folder, f"{name}.yaml", extra))
        groups = group_tasks(make_tasks(spec, folder / name))
        assert [len(g) for g in groups] == sizes, name
        if name == "plain":  # more workers than groups: the largest split to keep them busy
            split = group_tasks(make_tasks(spec, folder / name), workers=4)
            assert [len(g) for g in split] == [2, 2, 1, 1]
            assert sorted(t.id for g in split for t in g) == sorted(t.id for g in groups for t in g)
        for group in groups:  # a group is one flight: every option but the date is the same
            others = {json.dumps({k: v for k, v in t.options.items() if k != "map-date"},
                                 sort_keys=True) for t in group}  # fmt: skip
            assert len(others) == 1, name


def test_a_group_whose_flight_fails_gives_each_run_its_own_reason(folder: Path) -> None:
    base = {"plan": "plans/UT-200.plan", "air-start": True, "map": "nowhere/urban.tif"}
    spec = _spec(folder, "broken.yaml", {"base": base, "axes": {"map-date": [0, 1]}})
    assert [len(g) for g in group_tasks(make_tasks(load_spec(spec), folder / "broken"))] == [2]
    assert main(["sweep", str(spec), "--out", str(folder / "broken"), "--quiet"]) == 1
    rows = latest_rows(folder / "broken" / RESULTS)
    assert len(rows) == 2
    errors = {row["options"]["map-date"]: row["error"] for row in rows.values()}
    # Each tried alone after the shared flight failed: its own reason, one line.
    assert "nowhere/urban.tif" in errors[0] and "--map-date 1" in errors[1], errors
    for row in rows.values():
        assert "\n" not in row["error"] and row["wall_s"] > 0 and row["time_s"]["fly"] > 0
