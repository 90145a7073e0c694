"""A full disk under ``fly --no-camera``: one line, a non-zero exit, and ``trajectory.csv``
cut back to its last whole row (a real tmpfs a few dozen kB large)."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import pytest
from short_plans import write_short_plan
from tmpfs import tmpfs

from air_sitl.flightlog import TRAJECTORY_COLUMNS
from air_sitl.nav.columns import NAV_COLUMNS
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


@pytest.mark.parametrize("nav", ["truth", "ekf"])
def test_a_full_disk_stops_the_flight_with_one_line_and_whole_rows(
    tmp_path: Path, nav: str
) -> None:
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=300.0)
    with tmpfs(tmp_path / "small", size="48k") as disk:
        out = disk / "flight"
        done = subprocess.run(
            [sys.executable, "-m", "air_sitl", "fly", str(plan), "--air-start", "--no-camera",
             "--quiet", "--nav", nav, "--out", str(out)],
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        assert done.returncode == 2, done.stderr
        assert done.stderr == (
            f"air-sitl: error: {out / 'trajectory.csv'}: cannot write: No space left on device\n"
        )
        data = (out / "trajectory.csv").read_bytes()
        assert data.endswith(b"\n")
        rows = list(csv.reader(data.decode("ascii").splitlines()))
        columns = TRAJECTORY_COLUMNS + (NAV_COLUMNS if nav == "ekf" else ())
        assert tuple(rows[0]) == columns
        assert len(rows) > 50
        assert all(len(r) == len(columns) for r in rows)
        times = [int(r[0]) for r in rows[1:]]
        assert times == sorted(times) and len(set(times)) == len(times)
