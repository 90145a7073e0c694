"""Sweeps of short flights end to end: a 2x2x2 SPEC on the pool (-j 1, -j 2) and on a local Ray
give the same rows; a failing run is recorded and the others go on; a killed sweep resumes
(--resume) without redoing its finished runs; the report."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
import short_plans
import yaml

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from air_sitl.sweep.results import RESULTS, comparable, latest_rows, read_rows

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)
RUNS = 9  # the 2x2x2 product and one run over a map that does not exist
# The runs' frames are scored by deadreckon (no pixels) or not at all: the small camera (160 x
# 120, no noise: short_plans.SMALL_CAMERA), a third of the default frame's CPU.
SMALL = {"camera-width": 160, "camera-height": 120, "noise-sigma": 0}


@pytest.fixture(scope="module")
def spec(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("sweep-spec")
    (root / "plans").mkdir()
    short_plans.write_short_plan(root / "plans" / "UT-200.plan", HOME, leg_m=30.0)  # 100 frames
    content = {
        "base": {"plan": "plans/UT-200.plan", "air-start": True, "max-sim-time": 60, **SMALL},
        "axes": {"map-date": [0, 1], "wind": ["0@0", "5@270"], "seed": [1, 2]},
        "runs": [{"map": "nowhere/urban.tif", "seed": 3}],
        "methods": ["deadreckon"],
        "reference-date": 0,
    }
    path = root / "sweep.yaml"
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    return path


def sweep(spec: Path, out: Path, *where: str) -> int:
    return main(["sweep", str(spec), "--out", str(out), "--quiet", *where])


@pytest.fixture(scope="module")
def small(spec: Path) -> Path:
    """Three runs without methods: what the kill and Ctrl-C tests interrupt."""
    path = spec.with_name("small.yaml")
    content = {
        "base": {"plan": "plans/UT-200.plan", "air-start": True, "max-sim-time": 60, **SMALL},
        "axes": {"seed": [1, 2, 3]},
    }
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def pool2(spec: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("pool2") / "s"
    assert sweep(spec, out, "-j", "2") == 1  # 1: a run failed
    return out


@pytest.fixture(scope="module")
def pool1(spec: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("pool1") / "s"
    assert sweep(spec, out, "-j", "1") == 1
    return out


def rows_of(out: Path) -> dict[str, dict[str, Any]]:
    return {k: comparable(v) for k, v in latest_rows(out / RESULTS).items()}


def test_every_run_has_a_row_and_the_failing_one_its_reason(pool2: Path) -> None:
    rows = list(latest_rows(pool2 / RESULTS).values())
    assert len(rows) == RUNS == len(read_rows(pool2 / RESULTS))
    failed = [r for r in rows if r["error"]]
    assert len(failed) == 1 and "nowhere/urban.tif" in failed[0]["error"], failed
    assert "\n" not in failed[0]["error"] and failed[0]["options"]["seed"] == 3
    for row in rows:
        if row["error"]:
            continue
        assert row["summary"]["mission_completed"] is True
        assert row["summary"]["capture_frames"] >= 50 and "wall_time_s" not in row["summary"]
        report = row["eval"]["deadreckon"]
        assert report["frames"] == row["summary"]["capture_frames"]
        assert report["archive"] == f"runs/{row['id']}" == row["archive"]
        assert (pool2 / "runs" / row["id"] / "estimates" / "deadreckon.csv").is_file()
        assert row["wall_s"] > 0 and row["host"]
        assert row["reference_date"] == 0  # what the report names as each run's gap


def test_the_same_rows_on_one_worker_and_two(pool1: Path, pool2: Path) -> None:
    assert rows_of(pool1) == rows_of(pool2)


@pytest.fixture(scope="module")
def on_ray(spec: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("ray", reason="ray is not installed (pip install 'air-sitl[ray]')")
    out = tmp_path_factory.mktemp("ray") / "s"
    assert sweep(spec, out, "--ray") == 1
    return out


def test_the_same_rows_on_a_local_ray(on_ray: Path, pool2: Path) -> None:
    assert rows_of(on_ray) == rows_of(pool2)


def test_a_second_run_skips_every_done_run(spec: Path, pool2: Path) -> None:
    before = (pool2 / RESULTS).read_bytes()
    assert sweep(spec, pool2, "-j", "2", "--resume") == 1  # nothing run; the failed one stays
    assert (pool2 / RESULTS).read_bytes() == before


def test_a_killed_sweep_resumes_without_redoing_finished_runs(small: Path, tmp_path: Path) -> None:
    out = tmp_path / "s"
    cmd = [sys.executable, "-m", "air_sitl", "sweep", str(small), "--out", str(out), "-j", "1"]
    tmp = tmp_path / "tmp"  # the killed sweep's temporary folder
    tmp.mkdir()
    env = {**os.environ, "TMPDIR": str(tmp)}
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env)
    assert proc.stderr is not None
    for line in proc.stderr:  # a progress line comes after its row is on disk
        if line.startswith("sweep ["):
            break
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    proc.stderr.close()
    assert not list(tmp.glob("sweep-*"))  # a run killed mid-flight leaves nothing in /tmp
    first = (out / RESULTS).read_bytes()
    done = [r["id"] for r in read_rows(out / RESULTS)]
    assert 1 <= len(done) < 3
    assert sweep(small, out, "-j", "2", "--resume") == 0
    after = (out / RESULTS).read_bytes()
    assert after.startswith(first)  # the finished rows kept as they were
    ids = [r["id"] for r in read_rows(out / RESULTS)]
    assert len(ids) == len(set(ids)) == 3  # and none of them run again
    assert not list(out.rglob(".work-*"))  # the killed run's working folder taken over, gone


def test_ctrl_c_stops_cleanly_with_whole_rows(spec: Path, tmp_path: Path) -> None:
    # Twenty runs: the interrupt comes after the first, while many more are still to fly, so
    # the sweep cannot have finished first however the machine schedules the two processes.
    many = tmp_path / "many.yaml"
    content = {
        "base": {"plan": str(spec.parent / "plans" / "UT-200.plan"), "air-start": True},
        "axes": {"seed": list(range(1, 21))},
    }
    many.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    out = tmp_path / "s"
    cmd = [sys.executable, "-m", "air_sitl", "sweep", str(many), "--out", str(out), "-j", "1"]
    # A shell's background job starts with SIGINT ignored and Python keeps it so: give the
    # sweep the default, as a terminal's Ctrl-C would find it.
    proc = subprocess.Popen(
        cmd,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # noqa: PLW1509
    )
    assert proc.stderr is not None
    for line in proc.stderr:
        if line.startswith("sweep ["):
            break
    proc.send_signal(signal.SIGINT)
    rest = proc.stderr.read()
    assert proc.wait() == 130, rest
    assert "sweep interrupted" in rest and "Traceback" not in rest
    assert (out / RESULTS).read_bytes().endswith(b"\n")
    assert 1 <= len(read_rows(out / RESULTS)) < 20


def test_report_has_a_table_per_axis_and_a_png(pool2: Path) -> None:
    assert main(["sweep", "report", str(pool2), "--quiet"]) == 0
    md = (pool2 / "report.md").read_text()
    for axis in ("## map-date", "## wind"):
        assert axis in md
    assert "| 5@270 | deadreckon | 5 | 1 |" not in md  # the failed run has map-date 0 / 0@0
    assert "## Failed runs" in md and "nowhere/urban.tif" in md
    png = (pool2 / "report.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000
    info = json.loads((pool2 / "sweep.json").read_text())
    assert info["axes"] == ["map-date", "wind", "seed"] and len(info["runs"]) == RUNS


def test_an_external_localizer_runs_in_lockstep_on_its_own_port(spec: Path, tmp_path: Path) -> None:
    program = Path(__file__).resolve().parents[2] / "bridges" / "example_localizer.py"
    content = {
        # The localizer starts beside a loaded suite: fly's safety bound, not its 10 s default.
        "base": {
            "plan": str(spec.parent / "plans" / "UT-200.plan"),
            "air-start": True,
            "wait-timeout": 120,
        },
        "localizers": {"ex": f"{sys.executable} {program} --name ex --quiet"},
    }
    path = tmp_path / "ext.yaml"
    path.write_text(yaml.safe_dump(content), encoding="utf-8")
    assert sweep(path, tmp_path / "s") == 0
    (row,) = read_rows(tmp_path / "s" / RESULTS)
    report = row["eval"]["ex"]
    assert row["error"] is None and report["estimated_frames"] == report["frames"] >= 50
    archive = tmp_path / "s" / row["archive"]
    assert "estimates/ex.csv" in json.loads((archive / "manifest.json").read_text())["files"]
