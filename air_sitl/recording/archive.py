"""Record one flight into an archive folder: setup -> flight -> camera -> dataset writer.

Used by ``fly`` (one plan) and ``dataset`` (the 12 AIR scenarios). With a camera, the folder is
an AIR archive (:mod:`air_sitl.dataset`); without (``--no-camera``) it holds
``trajectory.csv`` and ``summary.json`` only, as the flight core wrote them (and
``gps_denial.json`` when GNSS is denied).

``resume=True`` continues an unfinished archive: it is trimmed to its last whole frame, the
flight is simulated again from t=0 (deterministic), frames already on disk are not rendered
again, and the result is byte-identical to an uninterrupted run with the same inputs.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from air_sitl.builder import FlightSetup, build_flight, open_camera, open_setup_map
from air_sitl.camera.coverage import DemCoverage, DemExtent, NodataFrames
from air_sitl.clock import NS_PER_S
from air_sitl.dataset.air_schema import (
    MANIFEST_JSON,
    RECORDING_JSON,
    SUMMARY_JSON,
    TRAJECTORY_CSV,
)
from air_sitl.dataset.estimates import fill_svo_columns
from air_sitl.dataset.manifest import read_manifest, refresh_manifest
from air_sitl.dataset.writer import ArchiveInfo, DatasetWriter, read_run_key, recover_partial
from air_sitl.errors import DatasetError, OptionError
from air_sitl.files import TMP_SUFFIX, sha256_file, write_json_atomic
from air_sitl.flightlog import NavTrajectoryWriter, TrajectoryWriter
from air_sitl.maps.choose import close_map
from air_sitl.maps.dates import date_fields
from air_sitl.mission.items import Mission
from air_sitl.outdir import claim_folder, empty_folder, is_nonempty_folder
from air_sitl.recording.inputs import GPS_DENIAL_JSON, archive_info_for, gps_denial_record
from air_sitl.recording.timing import OwnTime, timed_sinks, timed_source
from air_sitl.runner import Flight
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import SimSample

if TYPE_CHECKING:  # zenoh loads only for a flight on the bus
    from air_sitl.bus.hookup import BusHookup

ProgressFn = Callable[[SimSample, Flight], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class RecordingRequest:
    """Everything one recording needs: what flies (``setup``), where it goes, the bus."""

    setup: FlightSetup
    out: Path
    resume: bool = False
    overwrite: bool = False  # the one rule of air_sitl.outdir: an old run is removed first
    bus: BusHookup | None = None  # the zenoh bus side of the flight (air_sitl.bus.hookup)
    sinks: tuple[Sink, ...] = ()  # more sinks of the flight (the Foxglove live view)
    # False: the archive's files are written on the simulation thread, not on an I/O thread of
    # their own (a sweep worker is one core: a second thread only competes with it for the
    # GIL). The bytes are the same.
    io_thread: bool = True
    # What summary.json's ``plan`` names: None, the file flown (``setup.plan``); a sweep run
    # flies a copy of its SPEC's plan from its working folder and names the SPEC's plan here.
    summary_plan: str | None = None
    # Set: the wall seconds of the archive's own parts (camera, checks, trajectory, writer)
    # are added to it, the rest is the flight's (:mod:`.timing`: a sweep row's time_s).
    own_time: OwnTime | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class RecordingResult:
    """How a recording ended."""

    out: Path
    summary: dict[str, Any]
    manifest: dict[str, Any] | None  # None without a camera
    resumed_from_frame: int  # 0 for a fresh recording
    already_complete: bool = False

    @property
    def mission_completed(self) -> bool:
        """The mission flew to its end."""
        return bool(self.summary.get("mission_completed"))


def _already_complete(out: Path) -> RecordingResult | None:
    """The result of the complete archive in ``out`` (its inputs checked already by
    :func:`resume_problem`); None when it is not complete."""
    manifest_path = out / MANIFEST_JSON
    if not manifest_path.exists() or (out / RECORDING_JSON).exists():
        return None
    manifest = read_manifest(out)
    if not manifest or manifest.get("complete") is not True:
        return None
    summary: dict[str, Any] = {}
    if (out / SUMMARY_JSON).exists():
        summary = json.loads((out / SUMMARY_JSON).read_text(encoding="utf-8"))
    return RecordingResult(
        out=out,
        summary=summary,
        manifest=manifest,
        resumed_from_frame=int(manifest.get("frame_count", 0)),
        already_complete=True,
    )


def _only_temporary(out: Path) -> bool:
    """``out`` holds temporary files only (a recording stopped in its first instants)."""
    return all(p.name.endswith(TMP_SUFFIX) for p in out.iterdir())


def resume_problem(out: Path, info: ArchiveInfo) -> str | None:
    """None when ``out`` holds a recording of the inputs of ``info`` (unfinished: ``--resume``
    continues it; complete: nothing to do), else why not, in a short phrase."""
    manifest = read_manifest(out) if (out / MANIFEST_JSON).exists() else None
    if manifest and manifest.get("complete") is True and not (out / RECORDING_JSON).exists():
        diff = _complete_archive_differences(info, manifest)
        return f"a complete archive of other inputs ({'; '.join(diff)})" if diff else None
    found = read_run_key(out)
    if found is None and _only_temporary(out):
        return None  # stopped before its first file was whole: started again
    if found is None:
        return f"not an unfinished recording: no {RECORDING_JSON}"
    if found != info.run_key:
        keys = set(info.run_key) | set(found)
        diff = sorted(k for k in keys if info.run_key.get(k) != found.get(k))
        return f"a recording of other inputs ({', '.join(diff)} differ)"
    return None


def folder_problem(setup: FlightSetup, out: Path) -> str | None:
    """:func:`resume_problem` of ``out`` for the recording ``setup`` would make (its map
    opened and closed again): what ``dataset`` asks of every folder before anything flies."""
    if setup.camera is None or setup.plan is None:
        return "a recording without camera, which --resume cannot continue"
    map_source = open_setup_map(setup)
    try:
        info = archive_info_for(setup, map_source, plan_sha256=sha256_file(setup.plan))
    finally:
        close_map(map_source)
    return resume_problem(out, info)


# The manifest fields of a complete archive that hold the inputs deciding its bytes (its
# recording.json with the run key is gone once complete).
_COMPLETE_KEYS = ("plan_sha256", "map", "camera", "flight", "sensor_noise", "home")


def _complete_archive_differences(info: ArchiveInfo, manifest: Mapping[str, Any]) -> list[str]:
    """What differs between the inputs of this recording and a complete archive's manifest,
    one short phrase each (the plan by scenario name, the rest by field)."""
    out = []
    keys = (*_COMPLETE_KEYS, *(k for k in info.run_key if k in info.manifest))  # + GNSS denial
    for key in dict.fromkeys(keys):
        if key not in info.manifest or key not in manifest:
            continue  # not recorded by the archive's version: nothing to compare
        if info.manifest[key] == manifest[key]:
            continue
        if key == "plan_sha256":
            out.append(f"plan: archive {manifest.get('scenario', '?')}, this run {info.scenario}")
        else:
            out.append(f"{key} differs")
    return out


def _add_estimates(archive: Path, bus: BusHookup) -> None:
    """Estimates received over the bus into a finished archive: AIR's SvoX..SvoZ from
    ``--svo-columns NAME``, and the manifest's list of files (estimates/ came after it)."""
    positions = bus.svo_positions()
    if positions is not None:  # none received: the bus told already (estimator_watch)
        fill_svo_columns(archive, positions)
    elif bus.estimate_names():
        refresh_manifest(archive)


@dataclass(slots=True)
class ArchiveSide:
    """The parts of a recording that write one archive: its writer, camera and checks."""

    out: Path
    writer: DatasetWriter | None = None
    camera: FrameSource | None = None
    nodata: NodataFrames | None = None
    dem: DemCoverage | None = None
    first_frame: int = 0
    map_info: dict[str, Any] | None = None  # the manifest's map (its dates reach summary.json)
    done: RecordingResult | None = None  # complete already (--resume): nothing to fly
    summary: dict[str, Any] = field(default_factory=dict)  # summary.json, once finished

    @property
    def sinks(self) -> list[Sink]:
        """The sinks of the archive's checks (the writer and trajectory come after them)."""
        return [s for s in (self.nodata, self.dem) if s is not None]

    def abort(self) -> None:
        """Close what was opened, after an error before the flight."""
        if self.writer is not None:
            self.writer.close(None)  # type: ignore[arg-type]
        if self.camera is not None:
            self.camera.close()


def open_archive(
    setup: FlightSetup, out: Path, *, resume: bool, overwrite: bool, io_thread: bool
) -> ArchiveSide:
    """The writer, camera and checks of one camera archive (``setup.camera`` is set), its
    folder claimed by the one rule of :mod:`air_sitl.outdir` (``resume``, ``overwrite``)."""
    assert setup.plan is not None, "record_flight: an archive needs the plan file"
    side = ArchiveSide(out=out)
    map_source = open_setup_map(setup)
    try:
        info = archive_info_for(setup, map_source, plan_sha256=sha256_file(setup.plan))
        if isinstance(map_info := info.manifest.get("map"), dict):
            side.map_info = map_info
        resuming = claim_folder(
            out,
            overwrite=overwrite,
            resume=resume,
            resume_problem=lambda: resume_problem(out, info),
        )
        if resuming and _only_temporary(out):
            empty_folder(out)
            resuming = False
        if resuming:
            side.done = _already_complete(out)
            if side.done is not None:
                close_map(map_source)
                return side
            side.first_frame = recover_partial(out).frames_kept
        side.writer = DatasetWriter(out, info, first_frame=side.first_frame, threaded=io_thread)
    except BaseException:
        close_map(map_source)
        raise
    side.camera = open_camera(setup, map_source)
    side.nodata = NodataFrames(map_source.name)
    if isinstance(side.camera.renderer.surface, DemExtent):
        assert setup.camera is not None
        side.dem = DemCoverage(side.camera.renderer.surface, setup.camera)
    return side


def finish_archive(
    side: ArchiveSide, summary: dict[str, Any], capture_ticks: int, clock: OwnTime | None = None
) -> dict[str, Any]:
    """Check one archive's frames against the flight's ticks, add its own lines to
    ``summary`` (a copy), and write its manifest; returns the manifest (its wall time added
    to ``clock``)."""
    start = time.perf_counter()
    try:
        return _finish_archive(side, summary, capture_ticks)
    finally:
        if clock is not None:
            clock.seconds += time.perf_counter() - start


def _finish_archive(
    side: ArchiveSide, summary: dict[str, Any], capture_ticks: int
) -> dict[str, Any]:
    assert side.writer is not None
    writer, out = side.writer, side.out
    summary = dict(summary)
    writer.raise_if_failed()
    if writer.next_index != capture_ticks:
        msg = (
            f"{out}: {writer.next_index} frames written but {capture_ticks} "
            "capture ticks flown (a camera frame was lost)"
        )
        raise DatasetError(msg)
    summary["frames_written"] = writer.next_index
    if side.map_info is not None:
        summary["map"] = date_fields(side.map_info)  # the imagery's date, among the map's
    if side.first_frame:
        summary["resumed_from_frame"] = side.first_frame
    if side.nodata is not None and (record := side.nodata.record()) is not None:
        summary["frames_with_nodata"] = record
        print(side.nodata.message(), file=sys.stderr, flush=True)
    for line in side.dem.messages() if side.dem is not None else []:
        print(line, file=sys.stderr, flush=True)
    side.summary = summary
    return writer.finish(summary)


def record_flight(
    request: RecordingRequest,
    *,
    progress: ProgressFn | None = None,
    on_start: Callable[[Mission, int], None] | None = None,
) -> RecordingResult:
    """Fly ``request.setup`` and record it into ``request.out`` (see the module docstring).

    ``on_start(mission, first_frame)`` is called once the flight is assembled (progress bars).
    """
    setup = request.setup
    out = request.out
    options = setup.options
    if options.nav_aid == "mavlink":
        msg = "--nav-aid mavlink: MAVLink aids come over serve's links; fly takes a bus name"
        raise OptionError(msg)
    first_frame = 0

    sinks: list[Sink] = []
    side: ArchiveSide | None = None
    if setup.camera is not None:
        side = open_archive(
            setup,
            out,
            resume=request.resume,
            overwrite=request.overwrite,
            io_thread=request.io_thread,
        )
        if side.done is not None:
            return side.done
        first_frame = side.first_frame
        sinks.extend(timed_sinks(side.sinks, request.own_time))
    else:
        if request.resume and is_nonempty_folder(out) and not request.overwrite:
            msg = f"{out}: --resume needs a camera archive (without --no-camera)"
            raise DatasetError(msg)
        claim_folder(out, overwrite=request.overwrite)
        if options.gps_denied_ns:
            # Without a camera there is no manifest: the windows get a file of their own.
            write_json_atomic(out / GPS_DENIAL_JSON, gps_denial_record(options.gps_denied_ns))
    camera_source = timed_source(side.camera if side is not None else None, request.own_time)
    writer = side.writer if side is not None else None

    try:
        if request.bus is not None:
            bus_sinks, camera_source = request.bus.attach(
                home=setup.home,
                out=out,
                camera=setup.camera,
                seed=options.seed,
                frame_source=camera_source,
            )
            sinks.extend(bus_sinks)
        sinks.extend(request.sinks)
        trajectory_kind = NavTrajectoryWriter if options.nav == "ekf" else TrajectoryWriter
        trajectory = trajectory_kind(out / TRAJECTORY_CSV)
        own: list[Sink] = [trajectory] if writer is None else [trajectory, writer]
        sinks.extend(timed_sinks(own, request.own_time if side is not None else None))
        flight = build_flight(setup, sinks=sinks, camera=camera_source)
        if request.bus is not None and flight.nav is not None and options.nav_aid is not None:
            flight.nav.aid_feed = request.bus.nav_aid_feed(options.nav_aid)
    except BaseException:
        if side is not None:
            side.abort()
        raise
    flight.first_frame_to_render = first_frame
    if on_start is not None:
        on_start(setup.mission, first_frame)
    result = flight.run(
        stop=lambda sample: sample.autopilot.mission_completed or flight.stats.crashed is not None,
        max_sim_time_ns=int(options.max_sim_time_s * NS_PER_S),
        progress=progress,
    )
    trajectory.raise_if_failed()
    summary = dict(result.summary)
    summary["plan"] = request.summary_plan if request.summary_plan is not None else str(setup.plan)
    if request.bus is not None:
        summary.update(request.bus.after_flight())
    manifest = None
    if side is not None:
        manifest = finish_archive(side, summary, flight.counters.capture_ticks, request.own_time)
        summary = side.summary
        if request.bus is not None:
            _add_estimates(out, request.bus)
    else:
        write_json_atomic(out / SUMMARY_JSON, dict(sorted(summary.items())))
    return RecordingResult(
        out=out, summary=summary, manifest=manifest, resumed_from_frame=first_frame
    )
