"""A method that reads no imagery is localized and scored once per flight (issue 34): the runs
of the flight's other map dates take its result, which is what computing it gives (estimates
bytes, manifest entry, eval report); a method that reads imagery runs for every date."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
import short_plans
import yaml

from air_sitl.eval import evaluate
from air_sitl.localize import archive as localize_archive
from air_sitl.localize.methods import METHODS, reads_imagery
from air_sitl.state import GeoPoint
from air_sitl.sweep import load_spec, make_tasks, reuse
from air_sitl.sweep import run as sweep_run
from air_sitl.sweep.groups import group_tasks

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


@pytest.fixture(scope="module")
def flown(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Any, list[list[str]]]:
    """One flight over map dates 0 and 1 (one group), deadreckon and vo, run in this process
    with the methods' passes recorded: (folder, rows, the methods of each pass)."""
    root = tmp_path_factory.mktemp("reuse")
    (root / "plans").mkdir()
    short_plans.write_short_plan(root / "plans" / "UT-200.plan", HOME, leg_m=30.0)
    content = {
        "base": {"plan": "plans/UT-200.plan", "air-start": True, "max-sim-time": 60},
        "axes": {"map-date": [0, 1]},
        "methods": ["deadreckon", "vo"],
        "reference-date": 0,
    }
    (root / "spec.yaml").write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    (group,) = group_tasks(make_tasks(load_spec(root / "spec.yaml"), root / "out"))
    passes: list[list[str]] = []
    real = sweep_run.run_archive_methods

    def recorded(archive: Path, methods: Any, **kwargs: Any) -> Any:
        passes.append([m for m, _, _ in methods])
        return real(archive, methods, **kwargs)

    reuse.forget()
    with pytest.MonkeyPatch.context() as mp:  # a spy: the real pass runs
        mp.setattr(sweep_run, "run_archive_methods", recorded)
        rows = sweep_run.execute_group(group)
    reuse.forget()
    return root, rows, passes


def test_only_methods_that_read_no_imagery_declare_it() -> None:
    assert [m for m in METHODS if not reads_imagery(m)] == ["deadreckon"]
    assert reads_imagery("no-such-method")  # unknown: taken to read it


@pytest.mark.integration
def test_the_second_date_reuses_deadreckon_and_runs_vo(flown: tuple[Path, Any, Any]) -> None:
    _, rows, passes = flown
    assert [row["error"] for row in rows] == [None, None]
    assert passes == [["deadreckon", "vo"], ["vo"]]


@pytest.mark.integration
def test_a_reused_result_is_what_computing_it_gives(flown: tuple[Path, Any, Any]) -> None:
    root, rows, _ = flown
    archive = root / "out" / rows[1]["archive"]
    assert (archive / "manifest.json").is_file(), archive
    fresh = localize_archive.run_archive(archive, "deadreckon", name="fresh", seed=0)
    reused = archive / "estimates" / "deadreckon.csv"
    assert reused.read_bytes() == fresh.path.read_bytes()
    manifest = json.loads((archive / "manifest.json").read_text(encoding="utf-8"))
    files = manifest["files"]
    assert files["estimates/deadreckon.csv"] == files["estimates/fresh.csv"]
    report, scored = evaluate(archive, "fresh"), dict(rows[1]["eval"]["deadreckon"])
    for one in (report, scored):
        for key in ("archive", "estimate"):  # where and under which name
            one.pop(key, None)
    assert scored == report
    assert rows[1]["options"]["map-date"] == 1 and rows[1]["reference_date"] == 0


@pytest.mark.integration
def test_the_key_is_the_flights_inputs(flown: tuple[Path, Any, Any]) -> None:
    root, rows, _ = flown
    a, b = (root / "out" / row["archive"] for row in rows)
    key = reuse.key_of(a, "deadreckon", seed=0, reference_date=0)
    assert key is not None and key == reuse.key_of(b, "deadreckon", seed=0, reference_date=0)
    assert key != reuse.key_of(a, "deadreckon", seed=1, reference_date=0)
    assert reuse.key_of(a, "vo", seed=0, reference_date=0) is None
    assert reuse.key_of(root, "deadreckon", seed=0, reference_date=0) is None  # no archive
