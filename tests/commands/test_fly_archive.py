"""``air-sitl fly`` archives, end to end with real JSBSim, autopilot, map and camera.

A short plan (air start, 300 frames) keeps each flight to a second or two. Covers: an
independent minimal AIR reader written from SPEC section 1 only, determinism, SIGKILL at random
moments followed by ``check`` and ``--resume``, a full disk and a read-only folder, bad input.
"""

from __future__ import annotations

import contextlib
import csv
import json
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
import short_plans
from cli_errors import one_line_error

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.check import check_archive
from air_sitl.frames import ned2geodetic
from air_sitl.maps.open import open_map
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
LEG_M = 100.0  # capture leg: 100 m at 15 m/s, about 330 frames
WALL_CLOCK = {"summary.json", "manifest.json"}


def write_short_plan(path: Path, *, alt_m: float = 200.0, leg_m: float = LEG_M) -> Path:
    """The shared short capture flight, east of HOME."""
    return short_plans.write_short_plan(path, HOME, alt_m=alt_m, leg_m=leg_m)


def fly_args(plan: Path, out: Path, *extra: str) -> list[str]:
    return ["fly", str(plan), "--out", str(out), "--air-start", "--quiet", *extra]


def data_files(folder: Path) -> dict[str, bytes]:
    """Every file but the two that hold wall-clock figures (summary.json, and the manifest
    through summary.json's hash)."""
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in WALL_CLOCK
    }


def manifest_hashes(folder: Path) -> dict[str, str]:
    files = dict(json.loads((folder / "manifest.json").read_text())["files"])
    files.pop("summary.json")
    return files


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_short_plan(tmp_path_factory.mktemp("plan") / "UT-200.plan")


@pytest.fixture(scope="module")
def clean(plan: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("clean") / "a"
    assert main(fly_args(plan, out)) == 0
    return out


# -- an independent minimal reader, written from SPEC section 1 only ---------------------------

SPEC_HEADER = (  # the header line exactly as SPEC section 1 gives it
    "Filename,Latitude,Longitude,RelativeAltitude,ImuX,ImuY,ImuZ,ImuW,PoseX,PoseY,PoseZ,"
    "OrientationX,OrientationY,OrientationZ,OrientationW,MapX,MapY,SvoX,SvoY,SvoZ"
)


def minimal_read(folder: Path) -> list[dict[str, Any]]:
    """csv module, quotes stripped around Filename, MapX/MapY as int, everything else float."""
    with (folder / "metadata.csv").open(newline="") as f:
        rows = list(csv.reader(f))
    columns = SPEC_HEADER.split(",")
    assert rows[0] == columns
    out: list[dict[str, Any]] = []
    for fields in rows[1:]:
        row: dict[str, Any] = {}
        for name, value in zip(columns, fields, strict=True):
            if name == "Filename":
                row[name] = value.strip('"')
            elif name in ("MapX", "MapY"):
                row[name] = int(value)
            else:
                row[name] = float(value)
        out.append(row)
    return out


def _rotate_xyzw(q: tuple[float, float, float, float], v: np.ndarray) -> np.ndarray:
    x, y, z, w = q
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )
    return r @ v


def test_minimal_reader_counts_geometry_and_image_size(clean: Path) -> None:
    rows = minimal_read(clean)
    summary = json.loads((clean / "summary.json").read_text())
    jpgs = sorted(clean.glob("*.jpg"))
    assert len(rows) == summary["capture_frames"] == len(jpgs) > 250
    assert summary["mission_completed"] is True
    urban = open_map("urban", HOME, seed=0)
    worst_pose = worst_map = 0.0
    for row in rows[::7]:
        # PoseX/PoseY (ENU, relative to home) against Latitude/Longitude.
        lat, lon, _ = ned2geodetic(
            float(row["PoseY"]),
            float(row["PoseX"]),
            -float(row["PoseZ"]),
            HOME.lat_deg,
            HOME.lon_deg,
            HOME.alt_amsl_m,
        )
        north_err = (lat - row["Latitude"]) * 111_320.0
        east_err = (lon - row["Longitude"]) * 111_320.0 * math.cos(math.radians(lat))
        worst_pose = max(worst_pose, math.hypot(north_err, east_err))
        # The image centre ray (camera looks along body down = FLU -z) meets the ground.
        q = tuple(
            float(row[k]) for k in ("OrientationX", "OrientationY", "OrientationZ", "OrientationW")
        )
        ray = _rotate_xyzw(q, np.array([0.0, 0.0, -1.0]))
        pose = np.array([row["PoseX"], row["PoseY"], row["PoseZ"]])
        ground = pose + ray * (pose[2] / -ray[2])
        g_lat, g_lon, _ = ned2geodetic(
            ground[1], ground[0], 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m
        )
        mx, my = urban.latlon_to_map_px(g_lat, g_lon)
        worst_map = max(worst_map, math.hypot(mx - int(row["MapX"]), my - int(row["MapY"])))
        image = cv2.imread(str(clean / str(row["Filename"])))
        assert image is not None and image.shape == (480, 640, 3)
    assert worst_pose < 0.5, worst_pose
    assert worst_map < 2.0, worst_map


def test_the_archive_passes_check_and_has_every_file(clean: Path) -> None:
    assert main(["check", str(clean)]) == 0
    names = {p.name for p in clean.iterdir()}
    for name in (
        "metadata.csv",
        "frames.csv",
        "imu.csv",
        "camera.yaml",
        "UT-200.plan",
        "trajectory.csv",
        "summary.json",
        "manifest.json",
    ):
        assert name in names
    manifest = json.loads((clean / "manifest.json").read_text())
    assert manifest["complete"] is True and manifest["frame_count"] == len(minimal_read(clean))
    assert manifest["map"]["kind"] == "urban" and manifest["flight"]["seed"] == 0
    assert not any(n.endswith(".tmp") or n.startswith(".") for n in names)


def test_same_seed_gives_identical_archives(plan: Path, clean: Path, tmp_path: Path) -> None:
    out = tmp_path / "b"
    assert main(fly_args(plan, out, "--render-workers", "1")) == 0
    assert manifest_hashes(out) == manifest_hashes(clean)
    assert data_files(out) == data_files(clean)


def test_another_seed_gives_another_archive(plan: Path, clean: Path, tmp_path: Path) -> None:
    out = tmp_path / "c"
    assert main(fly_args(plan, out, "--seed", "7")) == 0
    a, b = manifest_hashes(out), manifest_hashes(clean)
    assert a["imu.csv"] != b["imu.csv"]
    assert a["frame_000000.jpg"] != b["frame_000000.jpg"]  # camera noise follows the seed


def _spawn_fly(plan: Path, out: Path, **kw: object) -> subprocess.Popen[bytes]:
    cmd = [sys.executable, "-m", "air_sitl", *fly_args(plan, out)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


def _signal_when(out: Path, proc: subprocess.Popen[bytes], marker: str, sig: int) -> bool:
    """Send ``sig`` to ``proc`` as soon as ``out/marker`` exists (an event, not a delay).

    Returns False when the flight ended by itself before the marker was seen.
    """
    target = out / marker
    while proc.poll() is None:
        if target.exists():
            proc.send_signal(sig)
            return True
        time.sleep(0.001)
    return False


def _kill_when(out: Path, proc: subprocess.Popen[bytes], marker: str | int) -> bool:
    """SIGKILL ``proc`` when ``out/marker`` appears, or (an int) when metadata.csv holds that
    many rows on disk; True when the kill ended the flight."""
    if isinstance(marker, str):
        _signal_when(out, proc, marker, signal.SIGKILL)
    else:
        metadata = out / "metadata.csv"
        while proc.poll() is None:
            with contextlib.suppress(OSError):
                if metadata.read_bytes().count(b"\n") > marker:  # header + rows
                    proc.send_signal(signal.SIGKILL)
                    break
            time.sleep(0.001)
    proc.wait()
    return proc.returncode == -signal.SIGKILL


def test_sigkill_at_random_moments_then_check_and_resume(
    plan: Path, clean: Path, tmp_path: Path
) -> None:
    total = len(minimal_read(clean))
    rng = np.random.default_rng(20261122)
    # Kills when a random frame of the capture has just been written, when metadata.csv holds a
    # random number of rows on disk (rows are flushed each simulated second, so those kills
    # always leave a partial archive), and as soon as the output folder exists (start-up).
    # Moments are events of the flight, so a busy machine moves none of them.
    frames = [int(rng.integers(1, total * 2 // 3))]
    rows = [int(rng.integers(1, total // 2))]
    markers: list[str | int] = [f"frame_{n:06d}.jpg" for n in frames] + rows + [""]
    kept: list[int] = []
    for k, marker in enumerate(markers):
        out = tmp_path / f"k{k}"
        proc = _spawn_fly(plan, out)
        landed = _kill_when(out, proc, marker)
        what = f"killed at {marker or 'the folder'!r} (landed: {landed})"
        if out.is_dir() and any(out.iterdir()):
            assert main(["check", str(out)]) == 3, what  # valid so far, unfinished
            if landed and (out / "metadata.csv").exists():
                with air_sitl.dataset.open(out) as archive:
                    kept.append(len(archive))
        assert main([*fly_args(plan, out), "--resume"]) == 0, what
        assert manifest_hashes(out) == manifest_hashes(clean), what
        assert data_files(out) == data_files(clean), what
    print("frames kept at each kill:", kept)
    assert any(0 < n < total for n in kept), kept


def test_resume_of_a_complete_archive_does_nothing(plan: Path, clean: Path, tmp_path: Path) -> None:
    out = tmp_path / "done"
    shutil.copytree(clean, out)
    before = data_files(out)
    assert main([*fly_args(plan, out), "--resume"]) == 0
    assert data_files(out) == before


def test_resume_with_other_inputs_is_refused(
    plan: Path, clean: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "partial"
    shutil.copytree(clean, out)
    (out / "manifest.json").unlink()
    (out / ".air-sitl-recording.json").write_text('{"run_key": {"flight": {"seed": 99}}}')
    err = one_line_error([*fly_args(plan, out), "--resume"], capsys)
    assert "--resume: a recording of other inputs (" in err and "flight" in err, err
    assert "--overwrite replaces it" in err


def _limit_file_size() -> None:
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # writes past the limit fail with EFBIG
    resource.setrlimit(resource.RLIMIT_FSIZE, (150_000, 150_000))


def test_a_full_disk_stops_with_one_line_and_the_folder_resumes(
    plan: Path, clean: Path, tmp_path: Path
) -> None:
    out = tmp_path / "full"
    proc = _spawn_fly(plan, out, preexec_fn=_limit_file_size)
    _, err = proc.communicate(timeout=120)
    _stopped_in_one_line_then_resumes(proc, err, "cannot write: File too large", plan, clean, out)


def _chattr(flag: str, path: Path) -> bool:
    try:
        result = subprocess.run(["chattr", flag, str(path)], capture_output=True, check=False)
    except FileNotFoundError:
        return False
    return result.returncode == 0


def test_a_folder_turning_read_only_stops_with_one_line_and_resumes(
    plan: Path, clean: Path, tmp_path: Path
) -> None:
    out = tmp_path / "ro"
    out.mkdir()
    if os.geteuid() != 0 or not _chattr("+i", out):
        pytest.skip("needs root and chattr to make a folder read-only for root")
    _chattr("-i", out)
    proc = _spawn_fly(plan, out)
    try:
        # Paused at its first frame, so the folder turns read-only mid-flight however busy the
        # machine is; then the next image fails.
        assert _signal_when(out, proc, "frame_000000.jpg", signal.SIGSTOP)
        assert _chattr("+i", out)
        proc.send_signal(signal.SIGCONT)
        _, err = proc.communicate()
    finally:
        _chattr("-i", out)
    why = "cannot write: Operation not permitted"
    _stopped_in_one_line_then_resumes(proc, err, why, plan, clean, out)


def _stopped_in_one_line_then_resumes(
    proc: subprocess.Popen[bytes], err: bytes, why: str, plan: Path, clean: Path, out: Path
) -> None:
    """fly stopped with exit 2 and one line saying ``why``; what it left checks valid, and
    ``--resume`` completes it to the bytes of a clean flight."""
    assert proc.returncode == 2
    lines = err.decode().strip().splitlines()
    assert len(lines) == 1 and why in lines[0], lines
    with air_sitl.dataset.open(out) as archive:
        report = check_archive(archive)
    assert report.valid, report.text()
    assert main([*fly_args(plan, out), "--resume"]) == 0
    assert data_files(out) == data_files(clean)


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["fly", "{missing}", "--out", "{tmp}/x"], "no_such.plan"),
        (["fly", "{plan}", "--out", "{tmp}/nonempty"], "holds another run"),
        (["fly", "{plan}", "--out", "{tmp}/y", "--render-workers", "many"], "--render-workers"),
        (["fly", "{plan}", "--out", "{tmp}/z", "--map", "moon"], "--map"),
        (["check", "{tmp}/nothing"], "no such archive"),
        (["check", "{plan}"], "not a folder or a readable zip"),
        (["export", "{tmp}/nothing", "--tum", "{tmp}/t.txt"], "no such archive"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    plan: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    argv: list[str],
    expected: str,
) -> None:
    (tmp_path / "nonempty").mkdir()
    (tmp_path / "nonempty" / "f").write_text("x")
    values = {"missing": str(tmp_path / "no_such.plan"), "tmp": str(tmp_path), "plan": str(plan)}
    err = one_line_error([a.format(**values) for a in argv], capsys)
    assert expected in err, err
