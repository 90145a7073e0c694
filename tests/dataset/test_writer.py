"""DatasetWriter on a scripted flight: archive contents, reader, checker, resume, SvoX..Z."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
from pathlib import Path

import pytest

import air_sitl.dataset
from air_sitl.camera.info import camera_yaml_for
from air_sitl.camera.model import CameraModel
from air_sitl.dataset.air_schema import AIR_COLUMNS, frame_filename
from air_sitl.dataset.check import check_archive
from air_sitl.dataset.estimates import fill_svo_columns
from air_sitl.dataset.writer import ArchiveInfo, DatasetWriter, recover_partial
from air_sitl.errors import DatasetError
from air_sitl.frames import geodetic2ned
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, CameraTick

from .synth import HOME, H, W, fly, samples

FRAMES = 120


def _info() -> ArchiveInfo:
    camera = camera_yaml_for(CameraModel(width_px=W, height_px=H))
    home = {"lat_deg": HOME.lat_deg, "lon_deg": HOME.lon_deg, "alt_amsl_m": HOME.alt_amsl_m}
    return ArchiveInfo(
        scenario="TEST",
        camera_yaml=camera,
        plan_name="TEST.plan",
        plan_text='{"fileType": "Plan"}\n',
        manifest={"home": home, "seed": 0},
        run_key={"seed": 0},
    )


def _record(folder: Path, *, threaded: bool = True, frames: int = FRAMES) -> dict[str, object]:
    writer = DatasetWriter(folder, _info(), threaded=threaded)
    fly(writer, frames)
    return writer.finish({"capture_distance_m": 1.0, "wall_time_s": 0.1})


def _data_files(folder: Path) -> dict[str, bytes]:
    return {
        p.relative_to(folder).as_posix(): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.name not in ("summary.json", "manifest.json")
    }


def test_archive_has_air_rows_frames_imu_and_a_manifest(tmp_path: Path) -> None:
    manifest = _record(tmp_path / "a")
    folder = tmp_path / "a"
    with (folder / "metadata.csv").open(newline="") as f:
        rows = list(csv.reader(f))
    assert tuple(rows[0]) == AIR_COLUMNS
    assert len(rows) == FRAMES + 1
    assert rows[1][0] == frame_filename(0)
    assert rows[1][-3:] == ["nan", "nan", "nan"]
    for row in rows[1:]:
        assert (folder / row[0]).is_file()
        int(row[15]), int(row[16])  # MapX/MapY are integers
    imu_lines = (folder / "imu.csv").read_text().splitlines()
    frames_lines = (folder / "frames.csv").read_text().splitlines()
    assert len(frames_lines) == FRAMES + 1
    # 200 Hz over the whole scripted flight: 2 s before, the capture, 1 s after.
    assert len(imu_lines) - 1 == (2000 + FRAMES * 20 + 1000) // 5 + 1
    assert manifest["frame_count"] == FRAMES
    assert manifest["complete"] is True
    assert list(manifest)[-1] == "complete"
    assert "summary.json" in manifest["wall_clock_files"]  # type: ignore[operator]
    assert not (folder / ".air-sitl-recording.json").exists()
    report = check_archive(air_sitl.dataset.open(folder))
    assert report.valid, report.text()
    assert report.status == "complete"
    assert report.max_position_error_m is not None and report.max_position_error_m < 0.01


def test_reader_yields_frames_in_order_with_timestamps(tmp_path: Path) -> None:
    _record(tmp_path / "a", frames=20)
    with air_sitl.dataset.open(tmp_path / "a") as archive:
        frames = list(archive)
    assert [f.index for f in frames] == list(range(20))
    assert [f.timestamp_ns for f in frames] == [2_000_000_000 + 20_000_000 * k for k in range(20)]
    assert frames[0].image.shape == (H, W, 3)
    n, e, _ = geodetic2ned(
        frames[5].row.lat_deg, frames[5].row.lon_deg, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0
    )
    assert math.hypot(e - frames[5].row.pose_enu_m[0], n - frames[5].row.pose_enu_m[1]) < 0.01


def test_threaded_and_inline_writers_and_repeated_runs_are_byte_identical(tmp_path: Path) -> None:
    a = _record(tmp_path / "a")
    b = _record(tmp_path / "b", threaded=False)
    assert _data_files(tmp_path / "a") == _data_files(tmp_path / "b")
    files_a = dict(a["files"])  # type: ignore[call-overload]
    files_b = dict(b["files"])  # type: ignore[call-overload]
    files_a.pop("summary.json")
    files_b.pop("summary.json")
    assert files_a == files_b


@pytest.mark.parametrize("cut", [0, 1, 37, 119])
def test_resume_after_a_cut_ends_byte_identical(tmp_path: Path, cut: int) -> None:
    _record(tmp_path / "clean")
    folder = tmp_path / "partial"
    writer = DatasetWriter(folder, _info(), threaded=False)
    fly(writer, FRAMES, stop_after_frame=cut)
    writer._post(("flush",))  # what reached the disk before the kill
    # Simulate a kill mid-write: a torn metadata line, an image past the rows, a temp file.
    with (folder / "metadata.csv").open("a") as f:
        f.write("frame_9999")
    (folder / frame_filename(cut + 1)).write_bytes(b"junk")
    (folder / "frame_000500.jpg.tmp").write_bytes(b"junk")
    partial_report = check_archive(air_sitl.dataset.open(folder))
    assert partial_report.valid, partial_report.text()
    assert partial_report.status.startswith("unfinished")
    found = recover_partial(folder)
    assert found.frames_kept == cut + 1
    assert found.run_key == {"seed": 0}
    writer = DatasetWriter(folder, _info(), first_frame=found.frames_kept)
    fly(writer, FRAMES, first_frame=found.frames_kept)
    writer.finish({"capture_distance_m": 1.0, "wall_time_s": 0.2})
    assert _data_files(folder) == _data_files(tmp_path / "clean")


def test_checker_finds_a_changed_image_and_a_missing_one(tmp_path: Path) -> None:
    _record(tmp_path / "a", frames=10)
    folder = tmp_path / "a"
    data = bytearray((folder / frame_filename(3)).read_bytes())
    data[-10] ^= 0xFF
    (folder / frame_filename(3)).write_bytes(bytes(data))
    (folder / frame_filename(5)).unlink()
    report = check_archive(air_sitl.dataset.open(folder))
    assert not report.valid
    text = "\n".join(report.errors)
    assert "frame_000003.jpg: SHA-256 differs" in text
    assert "image frame_000005.jpg is missing" in text


def test_checker_finds_a_moved_position_and_a_reordered_header(tmp_path: Path) -> None:
    _record(tmp_path / "a", frames=10)
    path = tmp_path / "a" / "metadata.csv"
    lines = path.read_text().splitlines(keepends=True)
    fields = lines[4].split(",")
    fields[8] = f"{float(fields[8]) + 3.0:.4f}"
    lines[4] = ",".join(fields)
    path.write_text("".join(lines))
    report = check_archive(air_sitl.dataset.open(tmp_path / "a"))
    assert any("PoseX/PoseY is 3.00 m" in e for e in report.errors), report.text()
    lines[0] = lines[0].replace("PoseX,PoseY", "PoseY,PoseX")
    path.write_text("".join(lines))
    with pytest.raises(DatasetError, match="not the 20 AIR columns"):
        air_sitl.dataset.open(tmp_path / "a")


def test_fill_svo_columns_rewrites_metadata_and_the_manifest(tmp_path: Path) -> None:
    _record(tmp_path / "a", frames=10)
    folder = tmp_path / "a"
    (folder / "estimates").mkdir()
    (folder / "estimates" / "vo.csv").write_text("frame,east_m,north_m,up_m\n0,1,2,3\n")
    filled = fill_svo_columns(folder, {0: (1.0, 2.0, 3.0), 4: (4.0, 5.5, 6.25)})
    assert filled == 2
    with air_sitl.dataset.open(folder) as archive:
        assert archive.rows[0].svo_enu_m == (1.0, 2.0, 3.0)
        assert archive.rows[4].svo_enu_m == (4.0, 5.5, 6.25)
        assert all(math.isnan(c) for c in archive.rows[1].svo_enu_m)
        report = check_archive(archive)
    assert report.valid, report.text()
    manifest = json.loads((folder / "manifest.json").read_text())
    assert "estimates/vo.csv" in manifest["files"]


def test_a_full_disk_is_a_one_line_error_and_the_rows_so_far_stay_valid(tmp_path: Path) -> None:
    folder = tmp_path / "a"
    writer = DatasetWriter(folder, _info(), threaded=True)
    # The disk fills up after the start: every later write to imu.csv fails with ENOSPC.
    full = os.open("/dev/full", os.O_WRONLY)
    os.dup2(full, writer._fds["imu.csv"])
    os.close(full)
    with pytest.raises(DatasetError, match=r"imu.csv: cannot write: No space left on device"):
        fly(writer, FRAMES)
    writer.close(None)  # type: ignore[arg-type]
    report = check_archive(air_sitl.dataset.open(folder))
    assert report.valid, report.text()


def test_unwritable_folder_is_a_one_line_error(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    with pytest.raises(DatasetError, match="cannot write"):
        DatasetWriter(tmp_path / "file" / "sub", _info())


def test_frames_outside_the_capture_window_are_not_archived(tmp_path: Path) -> None:
    # A camera kept on for an aid: window frames 0-9, 5 frames after it, window frames 10-19,
    # 5 more after. The archive holds the 20 window frames under their capture index.
    window = [f for _, f in samples(20) if f is not None]
    stream: list[tuple[CameraFrame, int | None]] = []
    for k, frame in enumerate(window):
        if k == 10:
            stream += [(frame, None)] * 5
        stream.append((frame, k))
    stream += [(window[-1], None)] * 5
    writer = DatasetWriter(tmp_path / "a", _info(), threaded=False)
    for index, (frame, capture) in enumerate(stream):
        tick = CameraTick(index=index, capture_index=capture)
        sample = dataclasses.replace(frame.sample, camera=tick)
        writer.on_frame(dataclasses.replace(frame, index=index, sample=sample))
    writer.close(FlightResult(mission_completed=True, sim_time_ns=0, wall_time_s=0.0))
    writer.finish({"capture_distance_m": 1.0, "wall_time_s": 0.1})
    folder = tmp_path / "a"
    names = sorted(p.name for p in folder.glob("frame_*.jpg"))
    assert names == [frame_filename(k) for k in range(20)]
    assert [(folder / n).read_bytes() for n in names] == [f.jpeg for f in window]
    with (folder / "frames.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert [(int(r["frame"]), int(r["sim_time_ns"])) for r in rows] == [
        (k, f.sim_time_ns) for k, f in enumerate(window)
    ]
    assert check_archive(air_sitl.dataset.open(folder)).valid
