"""Crash safety as a property: any state a killed writer can leave behind is checkable and
resumes to the same bytes.

The writer's order of writes means a killed run leaves each CSV as a byte prefix of its final
content (cut anywhere, even mid-line) and every row's image in place, possibly with more images
than rows and a temporary file. Hypothesis draws such states; each must pass ``check`` and, after
``recover_partial`` and a continued run, end byte-identical to an uninterrupted archive.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import air_sitl.dataset
from air_sitl.dataset.air_schema import frame_filename
from air_sitl.dataset.check import check_archive
from air_sitl.dataset.writer import DatasetWriter, recover_partial

from .synth import fly
from .test_writer import _data_files, _info

FRAMES = 40


@pytest.fixture(scope="module")
def clean(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("crash") / "clean"
    writer = DatasetWriter(folder, _info(), threaded=False)
    fly(writer, FRAMES)
    writer.finish({"wall_time_s": 0.0})
    return folder


def _rows_in(data: bytes) -> int:
    return max(0, data.count(b"\n") - 1)


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    meta_frac=st.floats(0.0, 1.0),
    frames_frac=st.floats(0.0, 1.0),
    imu_frac=st.floats(0.0, 1.0),
    extra_images=st.integers(0, 3),
    tmp_file=st.booleans(),
)
def test_any_killed_state_checks_and_resumes_to_the_same_bytes(
    clean: Path,
    meta_frac: float,
    frames_frac: float,
    imu_frac: float,
    extra_images: int,
    tmp_file: bool,
) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "a"
        folder.mkdir()
        for name in ("camera.yaml", "TEST.plan", ".air-sitl-recording.json"):
            src = clean / name
            if src.exists():
                shutil.copy(src, folder / name)
            else:
                (folder / name).write_text('{"scenario": "TEST", "run_key": {"seed": 0}}')
        rows = 0
        for name, frac in (
            ("metadata.csv", meta_frac),
            ("frames.csv", frames_frac),
            ("imu.csv", imu_frac),
        ):
            data = (clean / name).read_bytes()
            header = data.index(b"\n") + 1
            cut = data[: header + int(frac * (len(data) - header))]
            (folder / name).write_bytes(cut)
            if name != "imu.csv":
                rows = max(rows, _rows_in(cut) + 1)  # a torn row's image is in place too
        for k in range(min(FRAMES, rows + extra_images)):
            shutil.copy(clean / frame_filename(k), folder / frame_filename(k))
        if tmp_file:
            (folder / (frame_filename(rows + extra_images) + ".tmp")).write_bytes(b"\xff\xd8")
        with air_sitl.dataset.open(folder) as archive:
            report = check_archive(archive)
        assert report.valid, report.text()
        whole = min(
            _rows_in((folder / "metadata.csv").read_bytes()),
            _rows_in((folder / "frames.csv").read_bytes()),
        )
        kept = recover_partial(folder).frames_kept
        assert kept == whole
        writer = DatasetWriter(folder, _info(), first_frame=kept, threaded=False)
        fly(writer, FRAMES, first_frame=kept)
        writer.finish({"wall_time_s": 1.0})
        assert _data_files(folder) == _data_files(clean)
