"""``dataset`` says how much disk it will write and refuses when there is less free space.

The estimate comes from the paper's frame counts and the JPEG quality
(:mod:`air_sitl.dataset.size`). A real full file system (a 1 MB tmpfs, when this process
may mount one) and a patched free-space probe; ``--ignore-free-space`` flies anyway.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
from cli_errors import one_line_error
from short_plans import SMALL_CAMERA, write_short_plan
from tmpfs import tmpfs

from air_sitl.cli import main
from air_sitl.dataset import size
from air_sitl.dataset.scenarios import PAPER_TABLE
from air_sitl.state import GeoPoint

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def _need(err_line: str) -> str:
    """What the forecast's frames of these small frames need, by the size estimate."""
    frames = int(re.search(r"about (\d+) frames", err_line).group(1))  # type: ignore[union-attr]
    assert 150 <= frames <= 260, err_line  # the short plan's leg at cruise speed, 50 Hz
    return size.human_bytes(size.recording_bytes(frames, 90, 160, 120))


def test_all_twelve_scenarios_at_the_default_quality_are_about_11_gb() -> None:
    frames = sum(images for images, _distance in PAPER_TABLE.values())
    total = size.recording_bytes(frames, 90)
    assert 10.5e9 < total < 12.0e9
    assert size.human_bytes(total) == "11.5 GB"  # 113,474 frames
    # Fewer bytes at a lower quality, more pixels cost more.
    assert size.jpeg_bytes_per_frame(75) < size.jpeg_bytes_per_frame(90)
    assert size.jpeg_bytes_per_frame(90, 1280, 960) == pytest.approx(
        4 * size.jpeg_bytes_per_frame(90)
    )
    assert size.jpeg_bytes_per_frame(88) == pytest.approx((75_994 + 96_001) / 2 + 0.1 * 20_007)


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_short_plan(folder / "UC-200.plan", HOME, leg_m=60.0, alt_m=200.0, leg="north")
    return folder


def _argv(missions: Path, root: Path, *extra: str) -> list[str]:
    return ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--air-start",
            "--out", str(root), *SMALL_CAMERA, *extra]  # fmt: skip


def test_a_full_file_system_is_refused_in_one_line_before_anything_flies(
    missions: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(size, "free_bytes", lambda path: 1_000_000)
    root = tmp_path / "root"
    capsys.readouterr()
    assert main(_argv(missions, root)) == 2
    err = capsys.readouterr().err.splitlines()
    need = _need(err[0])
    assert err[0].startswith("dataset: 1 recording, about ") and f"about {need} into " in err[0]
    assert err[1] == (
        f"air-sitl: error: {root}: the recordings need about {need}, the file system has 1.0 MB "
        "free (--ignore-free-space to fly anyway)"
    )
    assert len(err) == 2
    assert not root.exists()  # nothing was made


def test_ignore_free_space_flies_anyway(
    missions: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(size, "free_bytes", lambda path: 1_000_000)
    root = tmp_path / "root"
    assert main(_argv(missions, root, "--ignore-free-space", "--quiet")) == 0
    assert (root / "UC-200" / "manifest.json").is_file()


def test_a_real_small_file_system_is_refused(missions: Path, tmp_path: Path) -> None:
    with tmpfs(tmp_path / "small", size="1m") as small:
        root = small / "air"
        run = subprocess.run(
            [sys.executable, "-m", "air_sitl", *_argv(missions, root)],
            capture_output=True, text=True, timeout=300, check=False, cwd=REPO,
        )  # fmt: skip
        assert run.returncode == 2, run.stderr
        last = run.stderr.splitlines()[-1]
        need = _need(run.stderr.splitlines()[0])
        assert last.startswith(f"air-sitl: error: {root}: the recordings need about {need}, ")
        assert "free (--ignore-free-space to fly anyway)" in last
        assert list(small.iterdir()) == []


def test_the_free_space_probe_reads_the_nearest_existing_folder(tmp_path: Path) -> None:
    with tmpfs(tmp_path / "small", size="1m") as small:
        assert 0 < size.free_bytes(small / "not" / "yet") <= 1024 * 1024


def test_a_resumed_folder_counts_only_the_frames_it_misses(tmp_path: Path) -> None:
    folder = tmp_path / "UC-200"
    folder.mkdir()
    for k in range(3):
        (folder / f"frame_{k:06d}.jpg").write_bytes(b"x")
    (folder / "metadata.csv").write_text("")
    assert size.frames_on_disk(folder) == 3
    assert size.frames_on_disk(tmp_path / "missing") == 0


def test_the_estimate_is_said_once_and_the_check_is_quiet_with_quiet(
    missions: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setattr(size, "free_bytes", lambda path: 1_000_000)
    line = one_line_error(_argv(missions, tmp_path / "root", "--quiet"), capsys)
    assert "--ignore-free-space" in line
