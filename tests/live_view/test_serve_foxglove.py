"""``serve --foxglove 127.0.0.1:0``: a served vehicle on the ground seen by a client written from
the protocol's spec: truth fixes at home, the preloaded mission, the STATUSTEXT it sends and
the mission a ground station uploads."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest
import short_plans
from mavlink.gcs import SAFETY_S, Gcs, serve
from pymavlink import mavutil

from air_sitl.mission.plan_file import read_plan

from .ws_client import FoxgloveClient

pytestmark = pytest.mark.integration


def _same(a: list[Any], b: list[Any]) -> bool:
    """The same points, to MAVLink's 1e-7 degree integers."""
    return len(a) == len(b) and all(
        abs(p[0] - q[0]) < 2e-7 and abs(p[1] - q[1]) < 2e-7 for p, q in zip(a, b, strict=True)
    )


def _waypoints(doc: dict[str, Any]) -> list[Any]:
    return [
        f["geometry"]["coordinates"]
        for f in doc["features"]
        if f["properties"]["name"].startswith("WP ")
    ]


V = "/air/uav0/"


def test_serve_streams_the_vehicle_and_its_statustext(tmp_path: Path) -> None:
    from air_sitl.state import GeoPoint

    home = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
    plan = short_plans.write_short_plan(tmp_path / "p.plan", home, leg_m=30.0)
    with (
        tempfile.TemporaryFile("w+") as err,
        serve(
            "--mavlink",
            "udpin:127.0.0.1:0",
            "--plan",
            str(plan),
            "--foxglove-image-hz",
            "0",
            "--foxglove",
            "127.0.0.1:0",
            stderr=err,
        ) as served,
    ):
        err.seek(0)
        port = int(re.search(r"foxglove: ws://127\.0\.0\.1:(\d+) \(uav0\)", err.read()).group(1))  # type: ignore[union-attr]
        client = FoxgloveClient("127.0.0.1", port)
        while not {V + "truth/fix", V + "mission", V + "log"} <= client.topics():
            client.recv()
        client.subscribe([V + "truth/fix", V + "mission", V + "log"])
        got: dict[str, list[object]] = {}
        while not {V + "truth/fix", V + "mission"} <= set(got):
            item = client.recv()
            if item[0] == "message":
                got.setdefault(item[1], []).append(item[3])
        fix = got[V + "truth/fix"][0]
        assert abs(fix.latitude - home.lat_deg) < 1e-4  # type: ignore[attr-defined]
        assert abs(fix.longitude - home.lon_deg) < 1e-4  # type: ignore[attr-defined]
        gcs = Gcs(f"udpout:127.0.0.1:{served.ports[0]}")
        try:
            gcs.connect()
            gcs.set_param("NAV_LOITER_RAD", float("nan"))  # refused with a STATUSTEXT
            text = gcs.wait_whole_text("NAV_LOITER_RAD: value nan")
            uploaded = read_plan(plan).items[:3]
            assert gcs.upload(uploaded) == mavutil.mavlink.MAV_MISSION_ACCEPTED
        finally:
            gcs.close()
        texts: list[str] = []  # the vehicle's STATUSTEXT on the log topic, in order
        plans: list[dict[str, Any]] = []  # the mission topic's documents
        points = [[it.lon_deg, it.lat_deg] for it in uploaded if it.is_nav and it.lat_deg]
        while text not in texts or not any(_same(_waypoints(p), points) for p in plans):
            topic, _, value = client.next_message()
            if topic == V + "log" and value.name == "vehicle":
                texts.append(value.message)
            elif topic == V + "mission":
                plans.append(json.loads(value.geojson))
        client.close()


def _spawned_workers(pid: int) -> list[int]:
    """The children multiprocessing spawned to run a target (not its resource tracker)."""
    path = Path(f"/proc/{pid}/task/{pid}/children")
    found = []
    for child in path.read_text().split() if path.exists() else []:
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"spawn_main" in cmdline:
            found.append(int(child))
    return found


def _ignores_sigint(pid: int) -> bool:
    """/proc's mask of ignored signals has SIGINT's bit."""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    mask = int(re.search(r"^SigIgn:\s*([0-9a-f]+)", status, re.M).group(1), 16)  # type: ignore[union-attr]
    return bool(mask & (1 << (signal.SIGINT - 1)))


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc (Linux)")
def test_ctrl_c_stops_serve_and_its_camera_process_without_a_traceback() -> None:
    """Ctrl-C reaches the terminal's whole process group: serve stops cleanly, and the view's
    camera process (which renders its images) leaves the stop to serve, printing nothing."""
    cmd = [sys.executable, "-m", "air_sitl", "serve", "--mavlink", "udpin:127.0.0.1:0",
           "--no-video", "--foxglove", "127.0.0.1:0"]  # fmt: skip
    with tempfile.TemporaryFile("w+") as err:
        proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=err, text=True, start_new_session=True
        )
        try:
            assert proc.stdout is not None
            assert "vehicle ready" in proc.stdout.readline()
            deadline = time.monotonic() + SAFETY_S  # only a broken serve gets there
            while not any(_ignores_sigint(c) for c in _spawned_workers(proc.pid)):
                assert proc.poll() is None and time.monotonic() < deadline, "no camera process"
                time.sleep(0.05)
            os.killpg(proc.pid, signal.SIGINT)
            assert proc.wait(timeout=SAFETY_S) == 0
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        err.seek(0)
        said = err.read()
    assert "Traceback" not in said and "KeyboardInterrupt" not in said, said
