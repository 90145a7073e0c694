"""The dataset logger: a Sink that writes an AIR archive folder, crash-safe at every instant.

Order of writes (what makes a folder valid whenever the process dies, SIGKILL included):

1. each JPEG goes to ``frame_NNNNNN.jpg.tmp`` and is renamed into place;
2. only then are its ``metadata.csv`` and ``frames.csv`` lines queued; queued lines reach the
   files (whole lines, ``os.write``) at least once per simulated second;
3. ``summary.json`` and then ``manifest.json`` (hashes, ``complete: true``) are written by
   :meth:`DatasetWriter.finish`, atomically, after everything else is closed.

A killed run leaves whole lines (the last one may be torn mid-write, which :func:`recover_partial`
and the checker handle) and no row without its image. The simulation thread only formats lines;
one I/O thread does the writes through a bounded queue, in order, so writes never stall the
simulation longer than the queue allows. The first OS error (disk full, read-only folder) stops
writing and is raised as a one-line :class:`~air_sitl.errors.DatasetError` at the next call.
"""

from __future__ import annotations

import dataclasses
import json
import os
import queue
import threading
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from air_sitl.clock import NS_PER_S
from air_sitl.dataset.air_schema import (
    AIR_HEADER,
    CAMERA_YAML,
    FRAMES_CSV,
    FRAMES_HEADERS,
    IMU_CSV,
    IMU_HEADER,
    METADATA_CSV,
    RECORDING_JSON,
    SUMMARY_JSON,
    frame_filename,
    frame_index_of,
    frames_header,
    frames_row,
    imu_row,
    metadata_row,
)
from air_sitl.dataset.manifest import hash_files, sha256_bytes, write_manifest
from air_sitl.errors import DatasetError
from air_sitl.files import TMP_SUFFIX, write_all, write_bytes_atomic, write_error, write_json_atomic
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import CameraFrame, GpsFix, SimSample

QUEUE_FRAMES = 64  # frames (about 100 kB each) the I/O thread may lag behind
FLUSH_PERIOD_NS = NS_PER_S
GPS_HISTORY = 256  # fixes kept (51 s at 5 Hz): far more than frames can lag behind


@dataclass(frozen=True, slots=True, kw_only=True)
class ArchiveInfo:
    """What a recording writes besides the data streams, and what identifies the run.

    ``manifest`` is merged into ``manifest.json`` (scenario, map, camera, noise, aircraft, wind,
    seed, software version, home ...). ``run_key`` identifies the inputs: ``--resume`` refuses a
    folder recorded with a different key.
    """

    scenario: str
    camera_yaml: str
    plan_name: str  # file name of the plan as flown, e.g. "FL-200.plan"
    plan_text: str
    manifest: Mapping[str, Any] = field(default_factory=dict)
    run_key: Mapping[str, Any] = field(default_factory=dict)
    nav_columns: bool = False  # frames.csv carries the onboard estimate (--nav ekf)
    agl_column: bool = False  # frames.csv ends with the height above the surface (--dem)


class DatasetWriter(NullSink):
    """Writes an archive folder from the samples and frames of one flight.

    ``first_frame`` > 0 continues a partial archive that :func:`recover_partial` trimmed to that
    many frames: earlier frames are expected to be absent (not rendered), later ones must arrive
    in order. ``imu.csv`` is rewritten from the start, as the flight is re-simulated from t=0.
    """

    def __init__(
        self,
        folder: Path,
        info: ArchiveInfo,
        *,
        first_frame: int = 0,
        threaded: bool = True,
    ) -> None:
        self.folder = folder
        self._folder_str = os.fspath(folder)
        self.info = info
        self.first_frame = first_frame
        self.next_index = first_frame
        self._outside = 0  # frames seen outside the capture window (not archived)
        self.error: DatasetError | None = None
        self.jpeg_hashes: dict[str, str] = {}
        self.first_time_ns: int | None = None
        self.last_time_ns: int | None = None
        # Recent GPS fixes: frames arrive after the simulation ran ahead (rendering threads),
        # so each frame takes the last fix at or before its own exposure time.
        self._gps_history: deque[GpsFix] = deque(maxlen=GPS_HISTORY)
        self._imu_lines: list[str] = []
        self._next_flush_ns = 0
        self._meta_buf: list[str] = []
        self._frames_buf: list[str] = []
        self._imu_buf: list[str] = []
        self._closed = False
        self._fds: dict[str, int] = {}
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise write_error(folder, err) from None
        marker = {"scenario": info.scenario, "run_key": dict(info.run_key)}
        write_json_atomic(folder / RECORDING_JSON, marker)
        self._open_streams()
        try:
            write_bytes_atomic(folder / CAMERA_YAML, info.camera_yaml.encode("utf-8"))
            write_bytes_atomic(folder / info.plan_name, info.plan_text.encode("utf-8"))
        except DatasetError:
            for fd in self._fds.values():
                os.close(fd)
            raise
        self._queue: queue.Queue[tuple[Any, ...] | None] | None = None
        self._thread: threading.Thread | None = None
        if threaded:
            self._queue = queue.Queue(maxsize=QUEUE_FRAMES)
            self._thread = threading.Thread(target=self._io_loop, name="dataset-io", daemon=True)
            self._thread.start()

    # -- simulation thread ---------------------------------------------------------------------

    def on_sample(self, sample: SimSample) -> None:
        """Queue the IMU line; hand everything to the disk once per simulated second."""
        self.on_sample_line(sample, imu_row(sample.imu))

    def on_sample_line(self, sample: SimSample, imu_line: str) -> None:
        """:meth:`on_sample` with the sample's ``imu.csv`` line formatted already (by
        :func:`~air_sitl.dataset.air_schema.imu_row`: archives of one flight share it)."""
        self._raise_if_failed()
        if sample.gps is not None:
            self._gps_history.append(sample.gps)
        self._imu_lines.append(imu_line)
        if sample.state.sim_time_ns >= self._next_flush_ns:
            self._next_flush_ns = sample.state.sim_time_ns + FLUSH_PERIOD_NS
            self._post(("imu", "".join(self._imu_lines)))
            self._imu_lines = []
            self._post(("flush",))

    def on_frame(self, frame: CameraFrame) -> None:
        """Queue the image and its two CSV lines (written in this order by the I/O thread).

        Only frames of the capture window are archived: a camera kept on for an aid also takes
        frames outside it (for the bus); they are skipped, and the window's frames numbered
        without them.
        """
        self._raise_if_failed()
        tick = frame.sample.camera
        if tick is not None and tick.capture_index is None:
            self._outside += 1
            return
        if self._outside:
            frame = dataclasses.replace(frame, index=frame.index - self._outside)
        if frame.index < self.first_frame:
            return
        if frame.index != self.next_index:
            msg = (
                f"{self.folder}: frame {frame.index} arrived where frame {self.next_index} "
                "was expected (frames must come in order)"
            )
            raise DatasetError(msg)
        self.next_index += 1
        if self.first_time_ns is None:
            self.first_time_ns = frame.sim_time_ns
        self.last_time_ns = frame.sim_time_ns
        name = frame_filename(frame.index)
        meta = metadata_row(name, frame.sample, frame.map_xy_px)
        extra = frames_row(
            frame,
            name,
            self._gps_at(frame.sim_time_ns),
            nav=self.info.nav_columns,
            agl=self.info.agl_column,
        )
        self._post(("frame", name, frame.jpeg, meta, extra))

    def close(self, result: FlightResult) -> None:
        """Write what is queued and close the files; never raises (see :meth:`finish`)."""
        if self._closed:
            return
        self._closed = True
        if self._imu_lines:
            self._post(("imu", "".join(self._imu_lines)), check=False)
            self._imu_lines = []
        self._post(("flush",), check=False)
        if self._thread is not None and self._queue is not None:
            self._queue.put(None)
            self._thread.join()
        for name, fd in self._fds.items():
            try:
                if self.error is None:
                    os.fsync(fd)
            except OSError as err:
                self.error = self.error or write_error(self.folder / name, err)
            finally:
                os.close(fd)
        self._fds = {}

    def finish(self, summary: Mapping[str, Any]) -> dict[str, Any]:
        """Seal a closed archive: ``summary.json``, then ``manifest.json`` last. Returns it."""
        if not self._closed:
            msg = f"{self.folder}: finish() before close()"
            raise DatasetError(msg)
        self._raise_if_failed()
        write_json_atomic(self.folder / SUMMARY_JSON, dict(sorted(summary.items())))
        files = hash_files(self.folder, self.jpeg_hashes)
        first_ns, last_ns = _frame_time_span(self.folder / FRAMES_CSV)
        info: dict[str, Any] = {"scenario": self.info.scenario}
        info.update(self.info.manifest)
        info.update(
            {
                "plan_file": self.info.plan_name,
                "frame_count": self.next_index,
                "frame_rate_hz": 50,
                "capture_distance_m": summary.get("capture_distance_m"),
                "mission_completed": summary.get("mission_completed"),
                "start_time_ns": first_ns,
                "end_time_ns": last_ns,
                "sim_time_s": summary.get("sim_time_s"),
            }
        )
        manifest = write_manifest(self.folder, info, files)
        (self.folder / RECORDING_JSON).unlink(missing_ok=True)
        return manifest

    def raise_if_failed(self) -> None:
        """Raise the first write error, if any (call after the flight returns)."""
        self._raise_if_failed()

    # -- internals -----------------------------------------------------------------------------

    def _gps_at(self, t_ns: int) -> GpsFix | None:
        for fix in reversed(self._gps_history):
            if fix.sim_time_ns <= t_ns:
                return fix
        return None

    def _raise_if_failed(self) -> None:
        if self.error is not None:
            raise self.error

    def _open_streams(self) -> None:
        append = self.first_frame > 0
        specs = (
            (METADATA_CSV, AIR_HEADER, append),
            (
                FRAMES_CSV,
                frames_header(nav=self.info.nav_columns, agl=self.info.agl_column),
                append,
            ),
            (IMU_CSV, IMU_HEADER, False),
        )
        for name, header, keep in specs:
            path = self.folder / name
            try:
                if not keep:  # the header in place at once: a kill never leaves an empty CSV
                    write_bytes_atomic(path, header.encode("ascii"))
                fd = os.open(path, os.O_WRONLY | os.O_APPEND)
            except (OSError, DatasetError) as err:
                for other in self._fds.values():
                    os.close(other)
                if isinstance(err, DatasetError):
                    raise  # write_bytes_atomic's line names the file already
                raise write_error(path, err) from None
            self._fds[name] = fd

    def _post(self, item: tuple[Any, ...], *, check: bool = True) -> None:
        if self._queue is None:
            if self.error is None:
                self._handle_safely(item)
            if check:
                self._raise_if_failed()
            return
        self._queue.put(item)

    def _io_loop(self) -> None:
        assert self._queue is not None
        while True:
            item = self._queue.get()
            if item is None:
                return
            if self.error is None:
                self._handle_safely(item)

    def _handle_safely(self, item: tuple[Any, ...]) -> None:
        try:
            self._handle(item)
        except DatasetError as err:
            self.error = err

    def _handle(self, item: tuple[Any, ...]) -> None:
        kind = item[0]
        if kind == "frame":
            _, name, jpeg, meta, extra = item
            write_bytes_atomic(os.path.join(self._folder_str, name), jpeg)
            self.jpeg_hashes[name] = sha256_bytes(jpeg)
            self._meta_buf.append(meta)
            self._frames_buf.append(extra)
        elif kind == "imu":
            self._imu_buf.append(item[1])
        elif kind == "flush":
            for name, buf in (
                (METADATA_CSV, self._meta_buf),
                (FRAMES_CSV, self._frames_buf),
                (IMU_CSV, self._imu_buf),
            ):
                if not buf:
                    continue
                data = "".join(buf).encode("ascii")
                buf.clear()
                try:
                    write_all(self._fds[name], data)
                except OSError as err:
                    raise write_error(self.folder / name, err) from None


def _frame_time_span(frames_csv: Path) -> tuple[int | None, int | None]:
    """Timestamps of the first and last rows of ``frames.csv`` (None when it has no rows)."""
    lines = frames_csv.read_text(encoding="ascii").splitlines()[1:]
    if not lines:
        return (None, None)
    return (int(lines[0].split(",", 2)[1]), int(lines[-1].split(",", 2)[1]))


@dataclass(frozen=True, slots=True)
class PartialArchive:
    """What :func:`recover_partial` found and kept in an unfinished archive."""

    frames_kept: int
    run_key: dict[str, Any] | None  # from the in-progress marker, None if it is missing
    trimmed_bytes: int  # torn or unmatched CSV bytes removed
    removed_files: int  # images past the last whole row and temporary files removed


def _complete_lines(path: Path, header: str) -> tuple[list[bytes], int] | None:
    """Whole lines after the header and the byte offset where they start; None if unusable."""
    if not path.exists():
        return None
    data = path.read_bytes()
    head = header.encode("ascii")
    if not data.startswith(head):
        return None
    body = data[len(head) :]
    end = body.rfind(b"\n") + 1
    return (body[:end].splitlines(keepends=True), len(head))


def read_run_key(folder: Path) -> dict[str, Any] | None:
    """The run key of an unfinished recording (its in-progress marker), None without one."""
    try:
        marker = json.loads((folder / RECORDING_JSON).read_text(encoding="utf-8"))
        return dict(marker["run_key"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def recover_partial(folder: Path) -> PartialArchive:
    """Trim an unfinished archive to its last whole frame so a re-run can continue it.

    A frame is whole when its image is in place and both its ``metadata.csv`` and
    ``frames.csv`` lines are complete. Later lines, torn lines, later images and temporary
    files are removed. Raises DatasetError when the folder is not an unfinished archive.
    """
    run_key = read_run_key(folder)
    meta = _complete_lines(folder / METADATA_CSV, AIR_HEADER)
    # Columns follow the flight's options (--nav ekf, --dem): the header says which.
    frames_head, extra = FRAMES_HEADERS[0], None
    for candidate in FRAMES_HEADERS:
        extra = _complete_lines(folder / FRAMES_CSV, candidate)
        if extra is not None:
            frames_head = candidate
            break
    kept = 0
    if meta is not None and extra is not None:
        for i, (m, f) in enumerate(zip(meta[0], extra[0], strict=False)):
            name = frame_filename(i)
            if not m.startswith(name.encode("ascii") + b",") or not f.startswith(
                f"{i},".encode("ascii")
            ):
                break
            if not (folder / name).is_file():
                break
            kept = i + 1
    trimmed = 0
    try:
        for path, lines, header in (
            (folder / METADATA_CSV, meta, AIR_HEADER),
            (folder / FRAMES_CSV, extra, frames_head),
        ):
            if lines is None:
                if path.exists():
                    trimmed += path.stat().st_size
                # The writer appends from frame `kept`: a clean file with its header, in place
                # at once (a kill here leaves the old file or the header, never an empty one).
                write_bytes_atomic(path, header.encode("ascii"))
                continue
            size = lines[1] + sum(len(line) for line in lines[0][:kept])
            trimmed += path.stat().st_size - size
            os.truncate(path, size)
        removed = 0
        for path in folder.iterdir():
            index = frame_index_of(path.name)
            if path.name.endswith(TMP_SUFFIX) or (index is not None and index >= kept):
                path.unlink()
                removed += 1
    except OSError as err:
        msg = f"{folder}: cannot trim the unfinished archive for --resume: {err.strerror}"
        raise DatasetError(msg) from None
    return PartialArchive(
        frames_kept=kept, run_key=run_key, trimmed_bytes=trimmed, removed_files=removed
    )
