"""Record one flight into an archive folder: plan -> flight -> camera -> dataset writer.

Used by ``fly`` (one plan) and ``dataset`` (the 12 AIR scenarios). With a camera, the folder is
an AIR archive (:mod:`air_sitl.dataset`); without (``--no-camera``) it holds
``trajectory.csv`` and ``summary.json`` only, as the flight core wrote them.

``resume=True`` continues an unfinished archive: it is trimmed to its last whole frame, the
flight is simulated again from t=0 (deterministic), frames already on disk are not rendered
again, and the result is byte-identical to an uninterrupted run with the same inputs.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from air_sitl import __version__
from air_sitl.clock import NS_PER_S
from air_sitl.dataset.air_schema import (
    MANIFEST_JSON,
    RECORDING_JSON,
    SUMMARY_JSON,
    TRAJECTORY_CSV,
)
from air_sitl.errors import DatasetError
from air_sitl.options import FlightOptions

if TYPE_CHECKING:
    from air_sitl.bus.hookup import BusHookup
    from air_sitl.camera.model import CameraModel
    from air_sitl.dataset.writer import ArchiveInfo
    from air_sitl.maps.base import MapSource
    from air_sitl.mission.items import Mission
    from air_sitl.runner import Flight
    from air_sitl.sinks import FrameSource
    from air_sitl.state import GeoPoint, SimSample

ProgressFn = Callable[["SimSample", "Flight"], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class MapChoice:
    """Which map the camera sees: ``spec`` is urban, forest or GeoTIFF path(s); None = by name."""

    spec: str | None = None
    seed: int = 0
    date: str | None = None


@dataclass(frozen=True, slots=True, kw_only=True)
class RecordingRequest:
    """Everything one recording needs; ``camera=None`` flies without rendering."""

    plan: Path
    out: Path
    options: FlightOptions = field(default_factory=FlightOptions)
    camera: CameraModel | None = None
    map: MapChoice = field(default_factory=MapChoice)
    render_workers: int = 2
    resume: bool = False
    scenario: str | None = None  # default: the plan's name
    bus: BusHookup | None = None  # zenoh bus and GNSS denial (air_sitl.bus.hookup)


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


def _jsonable(value: Any) -> Any:
    """A JSON round trip, so that keys compare equal with what a marker file holds."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def _sha256_file(path: Path) -> str:
    from air_sitl.dataset.manifest import sha256_file

    return sha256_file(path)


def _options_dict(options: FlightOptions) -> dict[str, Any]:
    return {
        "aircraft": options.aircraft,
        "air_start": options.air_start,
        "wind": {
            "speed_m_s": options.wind.speed_m_s,
            "from_deg": options.wind.from_deg,
            "turbulence": options.wind.turbulence,
        },
        "seed": options.seed,
        "max_sim_time_s": options.max_sim_time_s,
        "sensor_noise_scale": options.sensor_noise,
    }


def _camera_dict(camera: CameraModel) -> dict[str, Any]:
    return {
        **camera.settings(),
        "fx_px": camera.fx_px,
        "fy_px": camera.fy_px,
        "cx_px": camera.cx_px,
        "cy_px": camera.cy_px,
    }


def camera_yaml_for(camera: CameraModel) -> str:
    """``camera.yaml`` of a camera model (ROS camera_info layout + FOV, mounting, noise)."""
    from air_sitl.dataset.camera_info import (
        DEFAULT_MOUNTING,
        camera_yaml_dict,
        camera_yaml_text,
        matrix_to_quat,
    )

    r = camera.r_cam_to_body()
    q = matrix_to_quat([[float(r[i][j]) for j in range(3)] for i in range(3)])
    mounting = DEFAULT_MOUNTING
    if any(a != 0.0 for a in camera.mount_rpy_deg):
        mounting = f"{DEFAULT_MOUNTING}; then rotated by roll/pitch/yaw {camera.mount_rpy_deg} deg"
    content = camera_yaml_dict(
        width_px=camera.width_px,
        height_px=camera.height_px,
        fx_px=camera.fx_px,
        fy_px=camera.fy_px,
        cx_px=camera.cx_px,
        cy_px=camera.cy_px,
        q_camera_to_body_wxyz=q,
        mounting=mounting,
        extra={
            "mount_rpy_deg": [float(a) for a in camera.mount_rpy_deg],
            "noise_sigma": float(camera.noise_sigma),
            "jpeg_quality": int(camera.jpeg_quality),
        },
    )
    return camera_yaml_text(content)


def manifest_inputs(options: FlightOptions, camera: CameraModel, home: GeoPoint) -> dict[str, Any]:
    """What every archive's manifest records of the software, home, flight and camera."""
    return {
        "software": {"name": "air-sitl", "version": __version__},
        "home": _home_dict(home),
        "flight": _options_dict(options),
        "sensor_noise": _sensor_noise_dict(options.sensor_noise),
        "camera": _camera_dict(camera),
    }


def _home_dict(home: GeoPoint) -> dict[str, float]:
    return {"lat_deg": home.lat_deg, "lon_deg": home.lon_deg, "alt_amsl_m": home.alt_amsl_m}


def open_frame_source(
    map_source: MapSource, camera: CameraModel, *, seed: int, workers: int
) -> FrameSource:
    """The camera bridge rendering frames of ``map_source`` in ``workers`` threads."""
    from air_sitl.camera.bridge import CameraBridge
    from air_sitl.camera.render import Renderer

    source: FrameSource = CameraBridge(Renderer(map_source, camera, seed=seed), workers=workers)
    return source


def _already_complete(out: Path) -> RecordingResult | None:
    manifest_path = out / MANIFEST_JSON
    if not manifest_path.exists() or (out / RECORDING_JSON).exists():
        return None
    from air_sitl.dataset.manifest import read_manifest

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


def _write_json(path: Path, content: Mapping[str, Any]) -> None:
    from air_sitl.dataset.manifest import write_json_atomic

    write_json_atomic(path, content)


def archive_info_for(
    *,
    mission: Mission,
    scenario: str,
    home: GeoPoint,
    options: FlightOptions,
    camera: CameraModel,
    map_source: MapSource,
    plan_sha256: str,
    map_date: str | None = None,
) -> ArchiveInfo:
    """What a DatasetWriter needs besides the data: camera.yaml, the plan, manifest fields.

    ``run_key`` (the inputs that decide every byte) is what ``--resume`` compares.
    """
    from air_sitl.dataset.writer import ArchiveInfo
    from air_sitl.mission.plan_file import plan_text

    map_info = _jsonable(map_source.describe())
    if isinstance(map_info, dict) and "date" not in map_info:
        map_info["date"] = map_date  # GeoTIFF dates are files: the one chosen, as asked
    run_key = _jsonable(
        {
            "plan_sha256": plan_sha256,
            "flight": _options_dict(options),
            "map": map_info,
            "camera": _camera_dict(camera),
            "software_version": __version__,
        }
    )
    manifest = {
        **manifest_inputs(options, camera, home),
        "plan_sha256": plan_sha256,
        "map": map_info,
    }
    return ArchiveInfo(
        scenario=scenario,
        camera_yaml=camera_yaml_for(camera),
        plan_name=f"{scenario}.plan",
        plan_text=plan_text(mission),
        manifest=_jsonable(manifest),
        run_key=run_key,
    )


def _trim_for_resume(out: Path, run_key: Mapping[str, Any]) -> int:
    """Check that ``out`` is an unfinished recording of the same inputs; trim it; frames kept."""
    from air_sitl.dataset.writer import read_run_key, recover_partial

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


def record_flight(
    request: RecordingRequest,
    *,
    progress: ProgressFn | None = None,
    on_start: Callable[[Mission, int], None] | None = None,
) -> RecordingResult:
    """Fly ``request.plan`` and record it into ``request.out`` (see the module docstring).

    ``on_start(mission, first_frame)`` is called once the flight is assembled (progress bars).
    """
    from air_sitl.dataset.writer import DatasetWriter
    from air_sitl.flightlog import TrajectoryWriter
    from air_sitl.mission.plan_file import load_mission
    from air_sitl.runner import assemble_flight, home_of
    from air_sitl.sinks import Sink

    out = request.out
    options = request.options
    mission = load_mission(request.plan)
    scenario = request.scenario or mission.name or request.plan.stem
    home = home_of(mission)
    first_frame = 0
    resuming = request.resume and out.is_dir() and any(out.iterdir())
    if resuming and request.camera is not None:
        done = _already_complete(out)
        if done is not None:
            return done
    elif not resuming:
        prepare_out_dir(out)

    sinks: list[Sink] = []
    camera_source: FrameSource | None = None
    writer: DatasetWriter | None = None
    map_source: MapSource | None = None
    if request.camera is not None:
        from air_sitl.maps.open import default_map_for_plan, open_map

        spec = request.map.spec or default_map_for_plan(scenario)
        map_source = open_map(spec, home, seed=request.map.seed, date=request.map.date)
        try:
            info = archive_info_for(
                mission=mission,
                scenario=scenario,
                home=home,
                options=options,
                camera=request.camera,
                map_source=map_source,
                plan_sha256=_sha256_file(request.plan),
                map_date=request.map.date,
            )
            if request.bus is not None:
                info = request.bus.extend_archive_info(info)
            if resuming:
                first_frame = _trim_for_resume(out, info.run_key)
            writer = DatasetWriter(out, info, first_frame=first_frame)
        except BaseException:
            close_map = getattr(map_source, "close", None)
            if callable(close_map):
                close_map()
            raise
        camera_source = open_frame_source(
            map_source, request.camera, seed=options.seed, workers=request.render_workers
        )
    elif resuming:
        msg = f"{out}: --resume needs a camera archive (without --no-camera)"
        raise DatasetError(msg)

    try:
        if request.bus is not None:
            bus_sinks, camera_source = request.bus.attach(
                home=home,
                out=out,
                camera=request.camera,
                seed=options.seed,
                frame_source=camera_source,
            )
            sinks.extend(bus_sinks)
        sinks.append(TrajectoryWriter(out / TRAJECTORY_CSV))
        if writer is not None:
            sinks.append(writer)
        flight, _home, _initial = assemble_flight(
            mission, options, sinks=sinks, camera=camera_source, home=home
        )
    except BaseException:
        if writer is not None:
            writer.close(None)  # type: ignore[arg-type]
        if camera_source is not None:
            camera_source.close()
        raise
    flight.first_frame_to_render = first_frame
    if request.bus is not None:
        flight.sensors.gps_denied_ns = request.bus.gps_denied_ns
    if on_start is not None:
        on_start(mission, first_frame)
    result = flight.run(
        stop=lambda sample: sample.autopilot.mission_completed,
        max_sim_time_ns=int(options.max_sim_time_s * NS_PER_S),
        progress=progress,
    )
    summary = dict(result.summary)
    summary["plan"] = str(request.plan)
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
        manifest = writer.finish(summary)
        if request.bus is not None:
            request.bus.after_archive(out)
    else:
        _write_json(out / SUMMARY_JSON, dict(sorted(summary.items())))
    return RecordingResult(
        out=out, summary=summary, manifest=manifest, resumed_from_frame=first_frame
    )


def _sensor_noise_dict(scale: float) -> dict[str, Any]:
    from air_sitl.sensors import SensorNoise

    noise = SensorNoise().scaled(scale)
    return {k: (v if math.isfinite(v) else None) for k, v in asdict(noise).items()}
