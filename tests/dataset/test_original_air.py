"""Original AIR archives (metadata.csv beside the images, no manifest, no frames.csv), as
folders and zips: the reader, ``check`` and the exports accept them."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from rosbags.rosbag1 import Reader

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.check import check_archive
from air_sitl.dataset.writer import DatasetWriter

from .synth import fly
from .test_writer import _info

FRAMES = 15


@pytest.fixture(scope="module")
def air_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """An AIR-style folder: quoted Filename values, images, a plan, nothing else."""
    base = tmp_path_factory.mktemp("air")
    ours = base / "ours"
    writer = DatasetWriter(ours, _info())
    fly(writer, FRAMES)
    writer.finish({})
    air = base / "FL-200"
    air.mkdir()
    lines = (ours / "metadata.csv").read_text().splitlines()
    quoted = [lines[0]] + [f'"{ln.split(",", 1)[0]}",{ln.split(",", 1)[1]}' for ln in lines[1:]]
    (air / "metadata.csv").write_text("\n".join(quoted) + "\n")
    for jpg in ours.glob("*.jpg"):
        (air / jpg.name).write_bytes(jpg.read_bytes())
    (air / "FL-200.plan").write_text((ours / "TEST.plan").read_text())
    return air


def _zip(folder: Path, out: Path) -> Path:
    with zipfile.ZipFile(out, "w") as zf:
        for path in sorted(folder.iterdir()):
            zf.write(path, f"{folder.name}/{path.name}")
    return out


def test_reader_reads_an_air_folder_and_zip_alike(air_folder: Path, tmp_path: Path) -> None:
    zipped = _zip(air_folder, tmp_path / "FL-200.zip")
    with air_sitl.dataset.open(air_folder) as a, air_sitl.dataset.open(zipped) as b:
        assert a.kind == b.kind == "air"
        assert len(a) == len(b) == FRAMES
        assert a.rows[3].filename == "frame_000003.jpg"  # quotes stripped
        frames_a, frames_b = list(a), list(b)
    assert [f.timestamp_ns for f in frames_a] == [k * 20_000_000 for k in range(FRAMES)]
    assert all((x.image == y.image).all() for x, y in zip(frames_a, frames_b, strict=True))
    assert frames_b[2].row == frames_a[2].row


def test_check_accepts_air_archives_and_finds_their_problems(
    air_folder: Path, tmp_path: Path
) -> None:
    zipped = _zip(air_folder, tmp_path / "FL-200.zip")
    assert main(["check", str(zipped)]) == 0
    with air_sitl.dataset.open(air_folder) as archive:
        report = check_archive(archive)
    assert report.valid and report.status.startswith("original AIR"), report.text()
    broken = tmp_path / "broken"
    broken.mkdir()
    for path in air_folder.iterdir():
        (broken / path.name).write_bytes(path.read_bytes())
    (broken / "frame_000004.jpg").write_bytes(b"not a jpeg")
    assert main(["check", str(broken)]) == 1


def test_air_archive_exports_to_rosbag1_with_imu_per_frame(
    air_folder: Path, tmp_path: Path
) -> None:
    out = tmp_path / "air.bag"
    assert main(["export", str(air_folder), "--rosbag1", str(out)]) == 0
    with Reader(out) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert counts["/camera/image/compressed"] == counts["/imu"] == counts["/gt_pose"] == FRAMES
    assert "/svo_location" not in counts or counts["/svo_location"] == 0
