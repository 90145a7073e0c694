"""``serve --out`` and the disk: a folder that cannot be written is refused at start; a
recording that fails mid-flight (the disk fills up) is told to the ground stations as a
STATUSTEXT of severity ERROR, and the vehicle flies on. Real tmpfs, real serve, pymavlink."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from gcs import Gcs, serve
from pymavlink import mavutil
from short_plans import write_short_plan
from tmpfs import tmpfs

from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

M = mavutil.mavlink
HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def test_a_read_only_out_folder_is_refused_before_the_vehicle_is_ready(tmp_path: Path) -> None:
    with tmpfs(tmp_path / "ro", read_only=True) as folder:
        done = subprocess.run(
            [sys.executable, "-m", "air_sitl", "serve", "--out", str(folder / "rec"),
             "--mavlink", "udpin:127.0.0.1:0", "--home", "47.3769,8.5417,400"],
            capture_output=True, text=True, timeout=120, check=False,
        )  # fmt: skip
    assert done.returncode == 2
    assert done.stderr == (
        f"air-sitl: error: {folder / 'rec'}: cannot write in the --out folder: "
        "Read-only file system\n"
    )
    assert "vehicle ready" not in done.stdout


def test_a_full_disk_mid_flight_is_an_error_statustext_and_the_vehicle_flies_on(
    tmp_path: Path,
) -> None:
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=300.0)
    with tmpfs(tmp_path / "small", size="256k") as folder:
        args = ["--out", str(folder), "--plan", str(plan), "--speed", "0"]
        args += [
            "--mavlink",
            "udpin:127.0.0.1:0",
            "--camera-width",
            "320",
            "--camera-height",
            "240",
        ]
        with serve(*args) as s:
            gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
            try:
                gcs.connect()
                assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
                assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_ACCEPTED
                gcs.wait_text("Capture started")
                text = gcs.wait_whole_text("Recording stopped")
                error = next(m for m in gcs.statustexts if "Recording stopped" in m.text)
                assert error.severity == M.MAV_SEVERITY_ERROR
                assert "No space left on device" in text
                # The vehicle flies on: the mission goes on to its next items.
                seq = gcs.recv(["MISSION_CURRENT"]).seq
                while gcs.recv(["MISSION_CURRENT"]).seq <= seq:
                    pass
            finally:
                gcs.close()
            code, out = s.stop()
        assert code == 0
        assert "recording into" in out
