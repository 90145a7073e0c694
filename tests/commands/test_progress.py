"""Progress of long commands (issue 25, part 2): bars on a terminal, lines when piped.

The line rule (each tenth of the total, or 30 s without a line) with a fake clock; then the
real commands with stderr piped: ``fly`` (it printed nothing when piped) and ``dataset -j 2``,
whose scenarios fly in worker processes and report their frames to the parent.
"""

from __future__ import annotations

import io
import re
import subprocess
import sys
from pathlib import Path

import pytest
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.progress import LINE_EVERY_S, JobsProgress, Progress
from air_sitl.state import GeoPoint

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_piped_lines_come_at_each_tenth_then_the_end() -> None:
    out, clock = io.StringIO(), FakeClock()
    bar = Progress("UC-300", 1000, unit="frames", stream=out, clock=clock)
    assert not bar.tty  # a StringIO is no terminal
    for n in range(0, 1001, 25):
        clock.t += 1.0
        bar.update_to(n, f"sim {n // 50} s")
    bar.close()
    lines = out.getvalue().splitlines()
    percents = [int(re.search(r"\((\d+) %\)", line)[1]) for line in lines]  # type: ignore[index]
    assert percents == [10, 20, 30, 40, 50, 60, 70, 80, 90, 100], lines
    assert lines[0].startswith("UC-300: 100/1000 frames (10 %), ")
    assert "frames/s, ETA " in lines[0] and lines[0].endswith(", sim 2 s")
    assert "ETA" not in lines[-1]  # the end says how long it took


def test_a_count_past_its_estimated_total_ends_at_100_percent() -> None:
    """A flight's frame total is the paper's count; the flight may make a few more."""
    out, clock = io.StringIO(), FakeClock()
    jobs = JobsProgress(["FL-200"], {"FL-200": 100}, unit="frames", stream=out)
    jobs.overall.clock = jobs.jobs["FL-200"].clock = clock
    for n in (50, 100, 103):
        clock.t += 1.0
        jobs.update("FL-200", n)
    jobs.done("FL-200", 103, "done")
    jobs.close()
    last = out.getvalue().splitlines()[-1]
    assert last.startswith("overall: 103/103 frames (100 %)"), last
    assert "/?" not in out.getvalue()


def test_piped_lines_come_every_30_s_when_the_count_crawls() -> None:
    out, clock = io.StringIO(), FakeClock()
    bar = Progress("bench", 100, unit="cells", stream=out, clock=clock)
    for n in range(5):  # 4 % in 2 minutes: no tenth reached
        clock.t += LINE_EVERY_S / 2
        bar.update_to(n)
    assert len(out.getvalue().splitlines()) == 2  # at 30 s and 60 s
    unknown = Progress("localize vo", None, unit="frames", stream=out, clock=clock)
    unknown.update_to(10)  # its clock starts with its first count
    clock.t += LINE_EVERY_S
    unknown.update_to(50)
    assert out.getvalue().splitlines()[-1].startswith("localize vo: 50 frames, ")


def test_work_done_before_a_resume_counts_but_is_not_in_the_rate() -> None:
    """A resumed bench with 40 of 48 cells measured: 2 more in 4 s is 0.5 cells/s, not 10.5."""
    out, clock = io.StringIO(), FakeClock()
    bar = Progress("bench", 48, unit="cells", stream=out, clock=clock, initial=40)
    bar.update_to(40)
    clock.t += 4.0
    bar.update_to(42)
    bar.close()
    last = out.getvalue().splitlines()[-1]
    assert re.match(r"bench: 42/48 cells \(88 %\), +0.50 cells/s", last), last


def test_quiet_prints_nothing_and_a_terminal_gets_a_bar() -> None:
    quiet = io.StringIO()
    with Progress("fly", 10, stream=quiet, enabled=False) as bar:
        for n in range(11):
            bar.update_to(n)
        bar.note("a warning")
    assert quiet.getvalue() == ""
    tty = io.StringIO()
    with Progress("fly", 10, unit="items", stream=tty, tty=True) as bar:
        bar.update_to(10)
    assert "\r" in tty.getvalue() and "10/10" in tty.getvalue() and "100%" in tty.getvalue()


def test_jobs_lines_name_each_job_and_its_end() -> None:
    out = io.StringIO()
    jobs = JobsProgress(["UC-200", "FC-300"], {"UC-200": 100, "FC-300": 100}, stream=out)
    for frames in range(0, 101, 10):
        jobs.update("UC-200", frames)
    jobs.done("UC-200", 100, "done")
    jobs.close()
    text = out.getvalue()
    assert "UC-200: 10/100 frames (10 %)" in text
    assert "[1/2] UC-200: 100 frames, done" in text
    assert "overall: 100/200 frames (50 %)" in text


def test_fly_piped_prints_progress_lines(tmp_path: Path) -> None:
    plan = write_short_plan(tmp_path / "short.plan", HOME, leg_m=100.0)
    run = subprocess.run(
        [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(tmp_path / "out"),
         "--air-start", *SMALL_CAMERA],
        capture_output=True, text=True, timeout=600, check=False, cwd=REPO,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    lines = [ln for ln in run.stderr.splitlines() if re.match(r"short: \d+/\d+ items \(", ln)]
    assert len(lines) >= 2, run.stderr
    assert "items/s" in lines[0] and lines[-2].endswith(" frames")  # the note counts frames
    assert "6/6 items (100 %)" in lines[-1]
    # The items an air start skips are not a rate (it once said 1908396.91 items/s).
    rates = [float(r) for r in re.findall(r"([\d.]+) items/s", run.stderr)]
    assert rates and all(rate < 100 for rate in rates), run.stderr
    assert "\r" not in run.stderr  # no in-place bar into a pipe


def test_dataset_with_two_workers_reports_each_scenarios_frames_when_piped(
    tmp_path: Path,
) -> None:
    missions = tmp_path / "missions"
    missions.mkdir()
    # 150 m legs: about 500 frames each, forecast from the plans (the bars' totals); a line
    # at each tenth, the workers reporting every simulated second (50 frames).
    for name in ("UC-200", "UC-300"):
        write_short_plan(missions / f"{name}.plan", HOME, leg_m=150.0, leg="north")
    run = subprocess.run(
        [sys.executable, "-m", "air_sitl", "dataset", "--missions", str(missions),
         "--scenarios", "UC-200,UC-300", "-j", "2", "--air-start", "--out", str(tmp_path / "air"),
         *SMALL_CAMERA],
        capture_output=True, text=True, timeout=900, check=False, cwd=REPO,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    err = run.stderr.splitlines()
    forecast = re.match(r"dataset: 2 recordings, about (\d+) frames to write: about ", err[0])
    assert forecast, err[0]
    written = 0
    for name in ("UC-200", "UC-300"):
        # Lines with frame counts while the scenario flew in its worker process, then its end.
        during = [
            m for ln in err if (m := re.match(rf"{name}: (\d+)/(\d+) frames \(\d+ %\), ", ln))
        ]
        assert len(during) >= 2, run.stderr
        assert all(int(m[1]) <= int(m[2]) for m in during), run.stderr  # never past its total
        done = [m for ln in err if (m := re.match(rf"\[\d/2\] {name}: (\d+) frames, done", ln))]
        assert len(done) == 1, run.stderr
        frames = int(done[0][1])
        assert abs(int(during[0][2]) - frames) <= 0.2 * frames, (during[0][0], frames)
        written += frames
    assert abs(int(forecast[1]) - written) <= 0.2 * written, (err[0], written)
    assert any(ln.startswith("overall: ") and "frames/s" in ln for ln in err)
    # Again with --resume: nothing to fly, and the frames already there are not a rate.
    again = subprocess.run(
        [sys.executable, "-m", "air_sitl", "dataset", "--missions", str(missions),
         "--scenarios", "UC-200,UC-300", "-j", "2", "--air-start", "--out", str(tmp_path / "air"),
         "--resume", *SMALL_CAMERA],
        capture_output=True, text=True, timeout=900, check=False, cwd=REPO,
    )  # fmt: skip
    assert again.returncode == 0, again.stderr
    err = again.stderr.splitlines()
    assert err[0].startswith("dataset: 2 recordings (2 complete already), about 0 frames to write")
    rates = [float(r) for r in re.findall(r"([\d.]+) frames/s", again.stderr)]
    assert all(rate < 1e5 for rate in rates), again.stderr


@pytest.mark.parametrize("camera", [True, False], ids=["camera", "no-camera"])
def test_the_summary_says_frames_only_with_the_camera(tmp_path: Path, camera: bool) -> None:
    plan = write_short_plan(tmp_path / "short.plan", HOME, leg_m=60.0)
    extra = [*SMALL_CAMERA] if camera else ["--no-camera"]
    run = subprocess.run(
        [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(tmp_path / "out"),
         "--air-start", *extra],
        capture_output=True, text=True, timeout=600, check=False, cwd=REPO,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    capture = next(ln for ln in run.stdout.splitlines() if ln.startswith("  capture "))
    if camera:
        assert re.match(r"  capture +\d+ frames, \d+ m$", capture), capture
    else:
        assert re.match(r"  capture +no frames \(--no-camera\); capture window \d+ m$", capture)
        assert "frames" not in run.stderr.replace("no frames", "")
