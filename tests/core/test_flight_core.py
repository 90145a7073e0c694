"""The flight core end to end: AIR plans flown by JSBSim + our autopilot through the runner."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import pytest

from air_sitl.dataset.scenarios import PAPER_TABLE
from air_sitl.mission.plan_file import load_mission
from air_sitl.options import FlightOptions
from air_sitl.runner import assemble_flight

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.integration


@pytest.mark.parametrize("scenario", ["FC-200", "UL-300", "UR-200"])
def test_air_start_flight_meets_the_paper_and_the_tracking_bounds(scenario: str) -> None:
    mission = load_mission(REPO / "missions" / f"{scenario}.plan")
    flight, _, _ = assemble_flight(mission, FlightOptions(air_start=True))
    result = flight.run(stop=lambda s: s.autopilot.mission_completed, max_sim_time_ns=3600 * 10**9)
    s = result.summary
    images, distance_m = PAPER_TABLE[scenario]
    assert s["mission_completed"] is True
    assert abs(s["capture_frames"] / images - 1) <= 0.10
    assert abs(s["capture_distance_m"] / distance_m - 1) <= 0.05
    assert s["max_cross_track_m"] <= 15.0
    assert s["max_alt_error_m"] <= 10.0
    assert s["waypoints_reached"] == s["waypoints_total"]


def _start(plan: str, out: Path, *extra: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "air_sitl", "fly", str(REPO / "missions" / plan), "--out", str(out),
         "--air-start", "--no-camera", "--quiet", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip


def _fly(plan: str, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return _finish(_start(plan, out, *extra))


def _finish(proc: subprocess.Popen[str]) -> subprocess.CompletedProcess[str]:
    out, err = proc.communicate(timeout=300)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def test_fly_is_deterministic_and_seeds_matter_only_where_they_should(tmp_path: Path) -> None:
    # The first 100 simulated seconds (5,000 rows): the take-off is skipped, the turbulence
    # and the autopilot's turns are in it; the whole plan would only repeat them.
    wind = ("--wind", "4@300", "--turbulence", "0.3", "--max-sim-time", "100")
    # Side by side (one process per core): the same seed gives the same bytes anyway.
    procs = [_start("UC-300.plan", tmp_path / name, "--seed", seed, *wind) for name, seed in
             [("a", "5"), ("b", "5"), ("c", "6")]]  # fmt: skip
    runs = [_finish(p) for p in procs]
    for run in runs:  # exit 1: the mission is not completed when --max-sim-time ends it
        assert run.returncode == 1 and not run.stderr, run.stderr
    a, b, c = ((tmp_path / n / "trajectory.csv").read_bytes() for n in "abc")
    assert a == b
    assert a != c  # the seed drives the turbulence
    rows = a.decode().splitlines()
    assert len(rows) > 1000
    times = [int(r.split(",")[0]) for r in rows[1:6]]
    assert [t2 - t1 for t1, t2 in itertools.pairwise(times)] == [20_000_000] * 4


def test_a_wheel_aircraft_flies_a_plan_inside_its_own_speed_envelope(tmp_path: Path) -> None:
    run = _fly("UC-200.plan", tmp_path / "c172p", "--aircraft", "c172p")
    assert run.returncode == 0, run.stderr
    rows = (tmp_path / "c172p" / "trajectory.csv").read_text().splitlines()[1:]
    airspeeds = [float(r.split(",")[17]) for r in rows]
    assert min(airspeeds) > 25.0  # the c172p's own cruise, not our UAV's 15 m/s


def test_unknown_aircraft_is_a_one_line_error(tmp_path: Path) -> None:
    run = _fly("UC-200.plan", tmp_path / "x", "--aircraft", "no_such_plane")
    assert run.returncode == 2
    assert run.stderr.count("\n") == 1
    assert "no_such_plane" in run.stderr
    assert "Traceback" not in run.stderr
