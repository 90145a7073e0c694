"""A sweep run's ``summary.json`` names the plan its SPEC gave (a plan path, or the plan of a
scenario), not the temporary copy the worker flew: that one is gone when the run ends."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import short_plans
import yaml

from air_sitl.state import GeoPoint
from air_sitl.sweep import load_spec, make_tasks
from air_sitl.sweep.run import execute

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


def test_the_summary_names_the_specs_plan_not_the_flown_copy(tmp_path: Path) -> None:
    missions = tmp_path / "missions"
    missions.mkdir()
    short_plans.write_short_plan(missions / "UT-200.plan", HOME, leg_m=30.0)
    spec_path = tmp_path / "spec" / "one.yaml"
    spec_path.parent.mkdir()
    content = {
        "base": {"air-start": True, "no-camera": True, "max-sim-time": 60},
        "runs": [
            {"plan": "../missions/UT-200.plan", "altitude-offset": 50},  # relative to the SPEC
            {"scenario": "UT-200", "seed": 2},
        ],
    }
    spec_path.write_text(yaml.safe_dump(content), encoding="utf-8")
    tasks = make_tasks(load_spec(spec_path, missions=missions), tmp_path / "sweep")
    assert len(tasks) == 2
    expected = str((missions / "UT-200.plan").resolve())
    for task in tasks:
        row = execute(task)
        assert row["error"] is None, row["error"]
        summary = json.loads((Path(task.archive) / "summary.json").read_text())
        assert summary["plan"] == expected, summary["plan"]
        assert Path(summary["plan"]).is_file()
        assert row["summary"]["plan"] == task.plan_label  # the row keeps the SPEC's own words
    assert [t.plan_label for t in tasks] == ["../missions/UT-200.plan", "UT-200"]
