"""The archive writer is crash-safe at every instant, checked deterministically: after every
file-system call the writer makes (each os.write, os.replace, os.open ...) the folder is
inspected as a killed process would leave it. Every complete metadata.csv and frames.csv row
must name an image that is in place (not a ``.tmp``). A writer that appends a row before its
JPEG is renamed is caught here, not only by a wall-clock SIGKILL test."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

import air_sitl.dataset.writer as writer_module
from air_sitl.dataset.writer import DatasetWriter
from air_sitl.files import write_all, write_bytes_atomic

from .synth import fly
from .test_writer import _info

FRAMES = 30


def _rows_without_image(folder: Path) -> list[str]:
    """Complete CSV rows (ending in a newline) whose image is not in the folder."""
    missing = []
    for name, column in (("metadata.csv", 0), ("frames.csv", 2)):
        path = folder / name
        if not path.exists():
            continue
        text = path.read_text(encoding="ascii")
        lines = text.split("\n")[1:-1]  # header, then only whole lines (the last may be torn)
        for line in lines:
            image = line.split(",")[column]
            if not (folder / image).is_file():
                missing.append(f"{name}: {image}")
    return missing


class _Inspector:
    """Wraps os calls: after each one on the archive folder, inspect the folder."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.checks = 0
        self.failures: list[str] = []

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kw: Any) -> Any:
            result = fn(*args, **kw)
            if self.folder.exists():
                self.checks += 1
                bad = _rows_without_image(self.folder)
                if bad:
                    self.failures.append(f"after {fn.__name__} #{self.checks}: {bad[:3]}")
            return result

        return call


def _record_inspected(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> _Inspector:
    folder = tmp_path / "archive"
    inspector = _Inspector(folder)
    for name in ("write", "replace", "rename", "open", "close", "fsync", "unlink"):
        monkeypatch.setattr(os, name, inspector.wrap(getattr(os, name)))
    writer = DatasetWriter(folder, _info(), threaded=False)  # deterministic: no I/O thread
    fly(writer, FRAMES)
    writer.finish({"capture_distance_m": 1.0, "wall_time_s": 0.1})
    monkeypatch.undo()
    return inspector


def test_every_row_has_its_image_after_every_file_system_call(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    inspector = _record_inspected(tmp_path, monkeypatch)
    assert inspector.failures == []
    assert inspector.checks > 2 * FRAMES  # every image write and rename was a crash point
    images = sorted(p.name for p in (tmp_path / "archive").glob("*.jpg"))
    assert len(images) == FRAMES


def test_the_inspection_catches_a_row_written_before_its_image(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The deliberate bug: the CSV rows reach the file before the JPEG is renamed."""

    def buggy_handle(self: DatasetWriter, item: tuple[Any, ...]) -> None:
        if item[0] != "frame":
            return original(self, item)
        _, name, jpeg, meta, extra = item
        write_all(self._fds["metadata.csv"], meta.encode("ascii"))  # row first: the bug
        write_all(self._fds["frames.csv"], extra.encode("ascii"))
        write_bytes_atomic(os.path.join(self._folder_str, name), jpeg)
        return None

    original = writer_module.DatasetWriter._handle
    monkeypatch.setattr(writer_module.DatasetWriter, "_handle", buggy_handle)
    folder = tmp_path / "archive"
    inspector = _Inspector(folder)
    for name in ("write", "replace"):
        monkeypatch.setattr(os, name, inspector.wrap(getattr(os, name)))
    writer = DatasetWriter(folder, _info(), threaded=False)
    fly(writer, 5)
    monkeypatch.undo()
    assert inspector.failures, "a row before its image went unnoticed"


def test_check_calls_a_writer_killed_at_any_instant_of_its_start_unfinished(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`air-sitl check` as a user runs it on the folder a SIGKILL leaves, after each of the
    writer's file-system calls from its first to its third frame: always "valid so far,
    unfinished" (exit 3), never invalid. (A killed start left an empty metadata.csv, or
    camera.yaml without it, which check called invalid.)"""
    from air_sitl.cli import main

    folder = tmp_path / "archive"
    verdicts: list[tuple[str, int]] = []
    inside = False

    def wrap(fn: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any, **kw: Any) -> Any:
            nonlocal inside
            result = fn(*args, **kw)
            if not inside and folder.is_dir() and any(folder.iterdir()):
                inside = True  # check's own file-system calls are not crash points
                try:
                    code = main(["check", str(folder), "--no-images"])
                    verdicts.append((f"after {fn.__name__} #{len(verdicts) + 1}", code))
                finally:
                    inside = False
            return result

        return call

    for name in ("write", "replace", "rename", "open", "close", "fsync", "unlink"):
        monkeypatch.setattr(os, name, wrap(getattr(os, name)))
    writer = DatasetWriter(folder, _info(), threaded=False)
    fly(writer, FRAMES, stop_after_frame=2)
    monkeypatch.undo()
    capsys.readouterr()
    assert len(verdicts) > 10  # the start's files and the first frames' writes
    assert [v for v in verdicts if v[1] != 3] == [], verdicts
