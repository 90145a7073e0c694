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
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from air_sitl.builder import FlightSetup, build_flight, open_camera, open_setup_map
from air_sitl.bus.hookup import BusHookup
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
from air_sitl.files import sha256_file, write_json_atomic
from air_sitl.flightlog import NavTrajectoryWriter, TrajectoryWriter
from air_sitl.maps.choose import close_map
from air_sitl.mission.items import Mission
from air_sitl.recording.inputs import GPS_DENIAL_JSON, archive_info_for, gps_denial_record
from air_sitl.runner import Flight
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import SimSample

ProgressFn = Callable[[SimSample, Flight], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class RecordingRequest:
    """Everything one recording needs: what flies (``setup``), where it goes, the bus."""

    setup: FlightSetup
    out: Path
    resume: bool = False
    bus: BusHookup | None = None  # the zenoh bus side of the flight (air_sitl.bus.hookup)
    sinks: tuple[Sink, ...] = ()  # more sinks of the flight (the Foxglove live view)
    # False: the archive's files are written on the simulation thread, not on an I/O thread of
    # their own (a sweep worker is one core: a second thread only competes with it for the
    # GIL). The bytes are the same.
    io_thread: bool = True
    # What summary.json's ``plan`` names: None, the file flown (``setup.plan``); a sweep run
    # flies a copy of its SPEC's plan from its working folder and names the SPEC's plan here.
    summary_plan: str | None = None


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


def prepare_out_dir(path: Path) -> Path:
    """Create ``path``; refuse an existing non-empty folder or a file in the way."""
    if path.exists():
        if not path.is_dir():
            msg = f"{path}: exists and is not a folder"
            raise DatasetError(msg)
        if any(path.iterdir()):
            msg = f"{path}: folder exists and is not empty (choose another --out, or --resume)"
            raise DatasetError(msg)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"{path}: cannot create the output folder: {err.strerror}"
        raise DatasetError(msg) from None
    return path


def _already_complete(out: Path, info: ArchiveInfo) -> RecordingResult | None:
    """The result of a complete archive of the same inputs in ``out``; None when it is not
    complete; DatasetError naming what differs when it is a complete archive of other inputs
    (another plan, map, camera or flight options): never "nothing to do" for the wrong data."""
    manifest_path = out / MANIFEST_JSON
    if not manifest_path.exists() or (out / RECORDING_JSON).exists():
        return None
    manifest = read_manifest(out)
    if not manifest or manifest.get("complete") is not True:
        return None
    diff = _complete_archive_differences(info, manifest)
    if diff:
        msg = (
            f"{out}: --resume: the complete archive there was recorded from other inputs "
            f"({'; '.join(diff)}); choose another --out"
        )
        raise DatasetError(msg)
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


def _trim_for_resume(out: Path, run_key: Mapping[str, Any]) -> int:
    """Check that ``out`` is an unfinished recording of the same inputs; trim it; frames kept."""
    found = read_run_key(out)
    if found is None:
        msg = f"{out}: not an unfinished recording (no {RECORDING_JSON}); cannot --resume it"
        raise DatasetError(msg)
    if found != run_key:
        diff = sorted(k for k in set(run_key) | set(found) if run_key.get(k) != found.get(k))
        msg = (
            f"{out}: --resume with different inputs than the recording "
            f"({', '.join(diff)} differ); use the same plan and options"
        )
        raise DatasetError(msg)
    return recover_partial(out).frames_kept


def _add_estimates(archive: Path, bus: BusHookup) -> None:
    """Estimates received over the bus into a finished archive: AIR's SvoX..SvoZ from
    ``--svo-columns NAME``, and the manifest's list of files (estimates/ came after it)."""
    positions = bus.svo_positions()
    if positions is not None:  # none received: the bus told already (estimator_watch)
        fill_svo_columns(archive, positions)
    elif bus.estimate_names():
        refresh_manifest(archive)


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
    resuming = request.resume and out.is_dir() and any(out.iterdir())
    if not resuming:
        prepare_out_dir(out)

    sinks: list[Sink] = []
    camera_source: FrameSource | None = None
    writer: DatasetWriter | None = None
    nodata: NodataFrames | None = None
    dem: DemCoverage | None = None
    if setup.camera is not None:
        assert setup.plan is not None, "record_flight: an archive needs the plan file"
        map_source = open_setup_map(setup)
        try:
            info = archive_info_for(setup, map_source, plan_sha256=sha256_file(setup.plan))
            if resuming:
                done = _already_complete(out, info)
                if done is not None:
                    close_map(map_source)
                    return done
                first_frame = _trim_for_resume(out, info.run_key)
            writer = DatasetWriter(out, info, first_frame=first_frame, threaded=request.io_thread)
        except BaseException:
            close_map(map_source)
            raise
        camera_source = open_camera(setup, map_source)
        nodata = NodataFrames(map_source.name)
        sinks.append(nodata)
        if isinstance(camera_source.renderer.surface, DemExtent):
            dem = DemCoverage(camera_source.renderer.surface, setup.camera)
            sinks.append(dem)
    elif resuming:
        msg = f"{out}: --resume needs a camera archive (without --no-camera)"
        raise DatasetError(msg)
    elif options.gps_denied_ns:
        # Without a camera there is no manifest: the windows get a file of their own.
        write_json_atomic(out / GPS_DENIAL_JSON, gps_denial_record(options.gps_denied_ns))

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
        sinks.append(trajectory)
        if writer is not None:
            sinks.append(writer)
        flight = build_flight(setup, sinks=sinks, camera=camera_source)
        if request.bus is not None and flight.nav is not None and options.nav_aid is not None:
            flight.nav.aid_feed = request.bus.nav_aid_feed(options.nav_aid)
    except BaseException:
        if writer is not None:
            writer.close(None)  # type: ignore[arg-type]
        if camera_source is not None:
            camera_source.close()
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
    if writer is not None:
        writer.raise_if_failed()
        if writer.next_index != flight.counters.capture_ticks:
            msg = (
                f"{out}: {writer.next_index} frames written but {flight.counters.capture_ticks} "
                "capture ticks flown (a camera frame was lost)"
            )
            raise DatasetError(msg)
        summary["frames_written"] = writer.next_index
        if first_frame:
            summary["resumed_from_frame"] = first_frame
        if nodata is not None and (record := nodata.record()) is not None:
            summary["frames_with_nodata"] = record
            print(nodata.message(), file=sys.stderr, flush=True)
        for line in dem.messages() if dem is not None else []:
            print(line, file=sys.stderr, flush=True)
        manifest = writer.finish(summary)
        if request.bus is not None:
            _add_estimates(out, request.bus)
    else:
        write_json_atomic(out / SUMMARY_JSON, dict(sorted(summary.items())))
    return RecordingResult(
        out=out, summary=summary, manifest=manifest, resumed_from_frame=first_frame
    )
