"""With an aid (``fly --nav-aid``) the camera runs for the whole flight: frames reach the bus
(and the aid's localizer) before and after the capture window, to the end of the flight, while
the archive holds the capture window only (its frames, CSV rows and the logged estimates).
"""

from __future__ import annotations

import csv
import json
import subprocess
from pathlib import Path

import pytest
from short_plans import write_short_plan

from air_sitl.clock import CAMERA_PERIOD_NS
from tests.bus.helpers import HOME, cli
from tests.nav.truth_aid import fly_with_truth_aid

pytestmark = pytest.mark.integration


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def test_frames_reach_the_bus_for_the_whole_flight_and_the_archive_keeps_the_window(
    tmp_path: Path,
) -> None:
    # 60 m before the capture window, a 100 m capture leg (about 330 frames), 60 m after it.
    plan = write_short_plan(tmp_path / "UB-200.plan", HOME, leg_m=100.0, alt_m=200.0, lead_m=60.0)
    out = tmp_path / "out"
    est_out = fly_with_truth_aid(plan, out, "--air-start", "--gps-denied-after", "2", "--seed", "2")
    line = next(x for x in est_out.splitlines() if x.startswith("images "))
    images = [tuple(p) for p in json.loads(line[len("images ") :])]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["mission_completed"], summary
    n = summary["capture_frames"]
    start_ns = round(summary["capture_start_s"] * 1e9)
    end_ns = round(summary["capture_end_s"] * 1e9)
    # Every frame of the flight reached the subscriber, in order, at 50 Hz, from the first step
    # to the last tick before the flight stopped: before, in and after the capture window.
    assert images == [(k, k * CAMERA_PERIOD_NS) for k in range(len(images))]
    sim_end_ns = round(summary["sim_time_s"] * 1e9)
    assert sim_end_ns - CAMERA_PERIOD_NS < images[-1][1] <= sim_end_ns
    window = [t for _, t in images if start_ns <= t <= end_ns]
    assert len(window) == n
    before, after = start_ns // CAMERA_PERIOD_NS, len(images) - n - start_ns // CAMERA_PERIOD_NS
    assert before > 100 and after > 100, (before, n, after)
    # The aid's estimates of all those frames were fused, outside the window too.
    aid = summary["nav"]["aid"]
    assert aid["received"] >= len(images) - 2 and aid["fused"] > n + 200, aid
    # The archive: the capture window only, numbered from 0.
    jpegs = sorted(p.name for p in out.glob("frame_*.jpg"))
    assert jpegs == [f"frame_{k:06d}.jpg" for k in range(n)]
    assert len(_rows(out / "metadata.csv")) == n
    frames = _rows(out / "frames.csv")
    assert [(int(r["frame"]), int(r["sim_time_ns"])) for r in frames] == list(enumerate(window))
    logged = _rows(out / "estimates" / "aid.csv")
    assert [(int(r["frame"]), int(r["sim_time_ns"])) for r in logged] == list(enumerate(window))
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["frame_count"] == n and manifest["start_time_ns"] == start_ns
    check = subprocess.run(cli("check", str(out)), capture_output=True, text=True, check=False)
    assert check.returncode == 0, check.stdout + check.stderr
    scored = subprocess.run(
        cli("eval", str(out), "--estimate", "aid", "--json", str(tmp_path / "eval.json")),
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert scored.returncode == 0, scored.stderr
    report = json.loads((tmp_path / "eval.json").read_text())
    assert report["frames"] == n and report["estimated_frames"] == n
    assert report["horizontal_error_m"]["max"] < 0.01  # the truth, under the right frames
