"""A sweep worker is one core: its archive is written on the simulation thread, byte for byte
the archive ``air-sitl fly`` writes through its I/O thread."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import pytest
import short_plans
import yaml

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from air_sitl.sweep import load_spec, make_tasks
from air_sitl.sweep.run import execute

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)
WALL_CLOCK = ("wall_time_s", "realtime_factor")


def _files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in ("summary.json", "manifest.json")
    }


def _json_without(path: Path, keys: tuple[str, ...]) -> dict[str, object]:
    content = json.loads(path.read_text())
    return {k: v for k, v in content.items() if k not in keys}


def test_a_worker_writes_on_one_thread_the_bytes_fly_writes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    short_plans.write_short_plan(tmp_path / "UT-200.plan", HOME, leg_m=30.0)
    spec_path = tmp_path / "one.yaml"
    content = {"base": {"plan": "UT-200.plan", "air-start": True, "seed": 3, "map-date": 1}}
    spec_path.write_text(yaml.safe_dump(content), encoding="utf-8")
    (task,) = make_tasks(load_spec(spec_path), tmp_path / "sweep")

    threads: set[str] = set()
    original = threading.Thread.start

    def start(thread: threading.Thread) -> None:  # the real start, each thread's name noted
        threads.add(thread.name)
        original(thread)

    monkeypatch.setattr(threading.Thread, "start", start)
    row = execute(task)
    monkeypatch.undo()
    assert row["error"] is None, row["error"]
    assert "dataset-io" not in threads, threads

    flown = tmp_path / "fly"
    # The SPEC's plan as the sweep resolved it: both summaries name this file (the sweep's
    # worker flew a temporary copy of it).
    plan = str((tmp_path / "UT-200.plan").resolve())
    argv = ["fly", plan, *task.argv, "--out", str(flown), "--quiet"]
    assert main(argv) == 0
    swept = Path(task.archive)
    assert _files(swept).keys() >= _files(flown).keys()  # and the sweep's estimates
    assert {k: v for k, v in _files(swept).items() if k in _files(flown)} == _files(flown)
    summary = _json_without(swept / "summary.json", WALL_CLOCK)
    assert summary == _json_without(flown / "summary.json", WALL_CLOCK)
