"""``air-sitl dataset``: scenarios from a missions folder, in parallel, stats.csv, zips."""

from __future__ import annotations

import csv
import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from cli_errors import one_line_error
from short_plans import SMALL_CAMERA, write_short_plan

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.check import check_archive
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)
# The workers, kills, resumes and zips are tested, not the pixels: those runs render the small
# camera (a third of a 640 x 480 frame's CPU); the map tests keep the default one.


def write_plan_file(path: Path, leg_m: float, alt_m: float) -> None:
    """The shared short capture flight, its leg north."""
    write_short_plan(path, HOME, leg_m=leg_m, alt_m=alt_m, leg="north")


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_plan_file(folder / "UC-200.plan", 60.0, 200.0)
    write_plan_file(folder / "FC-300.plan", 90.0, 300.0)
    return folder


def test_two_scenarios_in_parallel_with_zips_and_the_air_table(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "root"
    argv = ["dataset", "--missions", str(missions), "--scenarios", "uc-200,FC-300"]
    argv += ["-j", "2", "--zip", "--air-start", *SMALL_CAMERA, "--out", str(root)]
    assert main(argv) == 0
    out = capsys.readouterr()
    assert "UC-200" in out.out and "total" in out.out
    assert "[2/2]" in out.err  # one progress line per scenario when not on a terminal
    with (root / "stats.csv").open(newline="") as f:
        rows = {r["scenario"]: r for r in csv.DictReader(f)}
    for name in ("UC-200", "FC-300"):
        manifest = json.loads((root / name / "manifest.json").read_text())
        assert int(rows[name]["images"]) == manifest["frame_count"] > 100
        assert rows[name]["paper_images"] in ("3422", "3450")
        assert float(rows[name]["images_ratio"]) == pytest.approx(
            manifest["frame_count"] / int(rows[name]["paper_images"]), abs=1e-3
        )
        assert manifest["map"]["kind"] == ("urban" if name.startswith("U") else "forest")
        with air_sitl.dataset.open(root / f"{name}.zip") as archive:
            report = check_archive(archive)
        assert report.valid and report.status == "complete", report.text()
    assert int(rows["total"]["images"]) == sum(int(rows[n]["images"]) for n in ("UC-200", "FC-300"))
    # --resume skips finished scenarios; without it the full folders are refused.
    assert main([*argv[:-2], "--out", str(root), "--resume"]) == 0
    assert main(argv) == 2
    assert "is not empty" in capsys.readouterr().err


def test_unknown_scenario_and_missing_missions_are_one_line_errors(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["dataset", "--missions", str(missions), "--scenarios", "XX-1"]
    assert "XX-1 has no plan" in one_line_error(argv, capsys)
    assert main(["dataset", "--missions", str(tmp_path / "none")]) == 2
    assert "--missions" in capsys.readouterr().err


def test_several_map_dates_give_one_folder_per_date(missions: Path, tmp_path: Path) -> None:
    root = tmp_path / "dates"
    argv = ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--dates", "0,2"]
    assert main([*argv, "--air-start", "--quiet", "--out", str(root)]) == 0
    a = json.loads((root / "UC-200@0" / "manifest.json").read_text())
    b = json.loads((root / "UC-200@2" / "manifest.json").read_text())
    assert a["map"]["date_index"] == 0 and b["map"]["date_index"] == 2
    assert a["frame_count"] == b["frame_count"]
    assert a["files"]["imu.csv"] == b["files"]["imu.csv"]  # same flight, other map date
    assert a["files"]["frame_000010.jpg"] != b["files"]["frame_000010.jpg"]


def test_a_geotiff_urban_map_is_used_and_a_map_without_home_is_refused_at_once(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tif = tmp_path / "urban.tif"
    origin = f"{HOME.lat_deg},{HOME.lon_deg}"
    argv = ["map", "make", "urban", "--out", str(tif), "--size-m", "1200", "1200"]
    assert main([*argv, "--gsd-m", "1.0", "--origin", origin]) == 0
    root = tmp_path / "tif"
    base = ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--quiet"]
    assert main([*base, "--air-start", "--map-urban", str(tif), "--out", str(root)]) == 0
    manifest = json.loads((root / "UC-200" / "manifest.json").read_text())
    assert manifest["map"]["source"] != "procedural"
    with air_sitl.dataset.open(root / "UC-200") as archive:
        assert check_archive(archive).valid
    far = tmp_path / "far.tif"
    argv = ["map", "make", "urban", "--out", str(far), "--size-m", "600", "600"]
    assert main([*argv, "--gsd-m", "2.0", "--origin", "10.0,10.0"]) == 0
    capsys.readouterr()
    err = one_line_error([*base, "--map-urban", str(far), "--out", str(tmp_path / "never")], capsys)
    assert "outside the map" in err
    assert not (tmp_path / "never").exists()


def _children(pid: int) -> list[int]:
    path = Path(f"/proc/{pid}/task/{pid}/children")
    return [int(p) for p in path.read_text().split()] if path.exists() else []


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_killing_a_parallel_run_leaves_no_worker_and_resume_matches_a_serial_run(
    missions: Path, tmp_path: Path
) -> None:
    base = ["dataset", "--missions", str(missions), "--scenarios", "UC-200,FC-300"]
    base += ["--air-start", "--quiet", *SMALL_CAMERA]
    serial = tmp_path / "serial"
    assert main([*base, "-j", "1", "--out", str(serial)]) == 0
    killed = tmp_path / "killed"
    cmd = [sys.executable, "-m", "air_sitl", *base, "-j", "2", "--out", str(killed)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 60
    workers: list[int] = []
    while time.monotonic() < deadline and not (killed / "FC-300" / "frame_000020.jpg").exists():
        workers = _children(proc.pid) or workers
        time.sleep(0.01)
    workers = _children(proc.pid) or workers
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert workers
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(_alive(w) for w in workers):
        time.sleep(0.05)
    assert not any(_alive(w) for w in workers), "a worker outlived its killed parent"
    assert main([*base, "-j", "2", "--out", str(killed), "--resume"]) == 0
    for name in ("UC-200", "FC-300"):
        a, b = (
            json.loads((r / name / "manifest.json").read_text())["files"] for r in (serial, killed)
        )
        a.pop("summary.json")
        b.pop("summary.json")
        assert a == b, name


def test_a_parallel_run_after_rendering_in_process_does_not_hang(
    missions: Path, tmp_path: Path
) -> None:
    """A script that rendered frames itself (OpenCV's thread pool running) then runs a pool.

    Forked workers inherited that pool's locks mid-use and could hang for ever; spawned ones
    start clean. Run in a subprocess so that a hang is a failed test, not a stuck suite.
    """
    script = f"""
import cv2, numpy
from air_sitl.cli import main
cv2.setNumThreads(2)
img = numpy.zeros((2000, 2000, 4), numpy.uint8)
for _ in range(20):
    cv2.warpAffine(img, numpy.eye(2, 3), (2000, 2000))  # parallel: the pool's threads run
raise SystemExit(main(["dataset", "--missions", {str(missions)!r}, "--scenarios",
                       "UC-200,FC-300", "--air-start", "--quiet", "-j", "2",
                       *{SMALL_CAMERA!r}, "--out", {str(tmp_path / "out")!r}]))
"""
    r = subprocess.run(
        [sys.executable, "-c", script], check=False, capture_output=True, text=True, timeout=60
    )
    assert r.returncode == 0, r.stderr
    for name in ("UC-200", "FC-300"):
        with air_sitl.dataset.open(tmp_path / "out" / name) as archive:
            assert check_archive(archive).valid
