"""The pytest plugin's ``air_sitl_vehicle``: a real served vehicle, talked to on MAVLink and zenoh.

Our suite uses the fixture as a user's suite does; a second pytest run (a subprocess, the way
a user's CI runs it) checks that the vehicle is gone after the test and that a vehicle which
cannot start fails the test with serve's own error line.
"""

from __future__ import annotations

import importlib.metadata
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import zenoh
from pymavlink import mavutil

from air_sitl.testing.served import ServedVehicle

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
UC200 = REPO / "missions" / "UC-200.plan"
UC200_HOME = (38.5125, -121.4935)
SAFETY_S = 120.0  # only a vehicle that stopped answering gets there


def heartbeat_of(url: str) -> object:
    """Heartbeats sent as a ground station until the vehicle's own heartbeat comes back."""
    link = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    try:
        deadline = time.monotonic() + SAFETY_S
        while time.monotonic() < deadline:
            link.mav.heartbeat_send(
                mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
            )
            msg = link.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if msg is not None and msg.get_srcSystem() == 1 and msg.get_srcComponent() == 1:
                return msg
    finally:
        link.close()
    raise AssertionError(f"no heartbeat from the vehicle on {url}")


@pytest.mark.air_sitl_serve("--plan", str(UC200), "--speed", "4")
def test_the_vehicle_answers_on_mavlink_udp_and_tcp(air_sitl_vehicle: ServedVehicle) -> None:
    assert air_sitl_vehicle.host == "127.0.0.1"
    assert 14540 not in {air_sitl_vehicle.mavlink_udp_port, air_sitl_vehicle.mavlink_tcp_port}
    for url in (air_sitl_vehicle.pymavlink_url, air_sitl_vehicle.pymavlink_tcp_url):
        hb = heartbeat_of(url)
        assert hb.autopilot == mavutil.mavlink.MAV_AUTOPILOT_PX4  # type: ignore[attr-defined]
        assert hb.type == mavutil.mavlink.MAV_TYPE_FIXED_WING  # type: ignore[attr-defined]
    assert air_sitl_vehicle.process.poll() is None


@pytest.mark.air_sitl_serve("--plan", str(UC200), "--speed", "4")
def test_the_vehicle_publishes_on_its_zenoh_endpoint(air_sitl_vehicle: ServedVehicle) -> None:
    conf = zenoh.Config()
    conf.insert_json5("connect/endpoints", json.dumps([air_sitl_vehicle.zenoh_endpoint]))
    conf.insert_json5("listen/endpoints", "[]")
    conf.insert_json5("scouting/multicast/enabled", "false")
    status: list[dict[str, object]] = []
    imu = threading.Event()
    prefix = air_sitl_vehicle.zenoh_key_prefix

    def on_sample(sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        if key == f"{prefix}/mission/status":
            status.append(json.loads(sample.payload.to_bytes()))
        elif key == f"{prefix}/imu":
            imu.set()

    with zenoh.open(conf) as session:
        session.declare_subscriber(f"{prefix}/**", on_sample)
        assert imu.wait(SAFETY_S), "no imu sample"
        deadline = time.monotonic() + SAFETY_S
        while not status and time.monotonic() < deadline:
            time.sleep(0.05)
    assert status, "no mission/status sample"
    home = status[0]["home"]
    assert isinstance(home, dict)
    assert (home["lat_deg"], home["lon_deg"]) == pytest.approx(UC200_HOME)  # the plan's home


USER_TESTS = """
import os, pathlib, pytest

@pytest.mark.air_sitl_serve("--speed", "2")
def test_running(air_sitl_vehicle):
    assert air_sitl_vehicle.process.poll() is None
    pathlib.Path("pid").write_text(str(air_sitl_vehicle.process.pid))

@pytest.mark.air_sitl_serve("--plan", "no/such.plan")
def test_bad_plan(air_sitl_vehicle):
    pass
"""


def _plugin_args() -> list[str]:
    """Nothing when air-sitl is installed with its entry point (pytest loads the plugin);
    else ``-p`` with the module, as a checkout on PYTHONPATH needs."""
    installed = importlib.metadata.entry_points(group="pytest11", name="air_sitl")
    return [] if installed else ["-p", "air_sitl.testing.pytest_plugin"]


def test_a_users_suite_gets_the_vehicle_stopped_and_serves_errors(tmp_path: Path) -> None:
    (tmp_path / "test_user.py").write_text(USER_TESTS)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), *sys.path[1:]]))
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider",
         "--rootdir", str(tmp_path), "-c", os.devnull, *_plugin_args(), "test_user.py"],
        cwd=tmp_path, capture_output=True, text=True, timeout=2 * SAFETY_S, env=env, check=False,
    )  # fmt: skip
    assert run.returncode == 1, run.stdout + run.stderr
    assert "1 passed" in run.stdout and "1 error" in run.stdout, run.stdout
    assert "no/such.plan" in run.stdout, run.stdout  # serve's own one-line error
    pid = int((tmp_path / "pid").read_text())
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)  # the vehicle of the passed test was stopped and reaped
