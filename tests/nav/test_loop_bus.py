"""The zenoh aid with real processes: ``fly --nav-aid aid --wait-for aid`` and an estimator
that answers every frame with the truth (``--publish-truth``) shifted east, in lockstep.

The estimate of frame k is fused once frame k+1 is out (lockstep guarantees it arrived), at
the frame's own time: two runs give the same bytes.
"""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest
from short_plans import write_short_plan

from tests.bus.helpers import HOME, cli, free_endpoint, start, stop, wait_for_line

pytestmark = pytest.mark.integration

ESTIMATOR = """
import json, sys
from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.bus.signals import wait_until_signalled
keys = KeySpace()
shift_east_m = float(sys.argv[2])
answered = []
with open_bus(BusConfig(listen=(sys.argv[1],), connect=())) as bus:
    out = bus.publisher(keys.estimate("aid"), encoding=codec.JSON_ENCODING, block=True)
    def on_truth(message):
        # The truth of each exposure carries its frame index: answer it (the answer depends on
        # nothing else, so two runs get the same answers).
        m = json.loads(message.payload)
        if m.get("frame") is None:
            return
        n, e, d = m["pos_ned_m"]
        out.put(json.dumps({"frame": m["frame"], "sim_time_ns": m["sim_time_ns"],
                            "enu_m": [e + shift_east_m, n, -d],
                            "cov_enu_m2": [4, 0, 0, 0, 4, 0, 0, 0, 9]}).encode())
        answered.append(m["frame"])
    bus.subscribe(keys.truth, on_truth)
    bus.subscribe(keys.image, lambda message: None)  # lockstep waits for a frame subscriber
    print("ready", flush=True)
    wait_until_signalled()
    print(f"answered {len(answered)}", flush=True)
"""


def aided_flight(tmp_path: Path, plan: Path, name: str, shift_east_m: float = 0.0) -> Path:
    endpoint = free_endpoint()
    script = tmp_path / "estimator.py"
    script.write_text(ESTIMATOR)
    out = tmp_path / name
    # The estimator listens first so that it hears every truth sample of the capture window.
    est = start([sys.executable, str(script), endpoint, str(shift_east_m)])
    try:
        wait_for_line(est, "ready")
        run = subprocess.run(
            # From the ground: the capture starts long after the sessions have met.
            cli("fly", str(plan), "--out", str(out), "--quiet",
                "--zenoh-connect", endpoint, "--publish-truth", "--nav-aid", "aid",
                "--wait-for", "aid", "--gps-denied-after", "35", "--seed", "4"),
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        est_code, _stdout, stderr = stop(est)
    assert run.returncode == 0, run.stderr
    assert est_code == 0, stderr
    return out


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_short_plan(
        tmp_path_factory.mktemp("plan") / "UB-200.plan", HOME, leg_m=600.0, alt_m=80.0
    )


def test_a_lockstep_aid_over_zenoh_is_fused_and_deterministic(plan: Path, tmp_path: Path) -> None:
    a = aided_flight(tmp_path, plan, "a")
    b = aided_flight(tmp_path, plan, "b")
    summary = json.loads((a / "summary.json").read_text())
    nav = summary["nav"]
    frames = summary["capture_frames"]
    # Every frame's estimate but the last (it comes after the last step) reached the filter;
    # the gate refuses a few right after GNSS is lost (the estimate was still GNSS-tight).
    assert nav["aid"]["name"] == "aid" and nav["aid"]["received"] >= frames - 2, nav["aid"]
    assert nav["aid"]["fused"] >= 0.95 * frames, nav["aid"]["rejected_by_reason"]
    assert nav["aid"]["rejected"] <= 10, nav["aid"]
    assert nav["horizontal_error_denied_m"]["p95"] < 5.0, nav
    for name in ("trajectory.csv", "frames.csv", "metadata.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    strip = ("wall_time_s", "realtime_factor", "lockstep_wait_wall_s", "plan")
    sa = {k: v for k, v in summary.items() if k not in strip}
    sb = {k: v for k, v in json.loads((b / "summary.json").read_text()).items() if k not in strip}
    assert sa == sb
    with (a / "frames.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows and all(r["nav_east_m"] != "" for r in rows)
