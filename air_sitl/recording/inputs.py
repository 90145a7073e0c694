"""What an archive records of its inputs: software, home, flight options, sensors, camera, map.

Shared by the recordings of ``fly``/``dataset`` (:mod:`air_sitl.recording.archive`) and of
``serve`` (:mod:`air_sitl.recording.capture`), so every archive describes them alike.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from typing import Any

from air_sitl import __version__
from air_sitl.builder import FlightSetup
from air_sitl.camera.info import camera_fields, camera_yaml_for
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.dataset.writer import ArchiveInfo
from air_sitl.maps.base import MapSource
from air_sitl.mission.plan_file import plan_text
from air_sitl.options import OPEN_END_NS, DenialWindows, FlightOptions
from air_sitl.sensors import SensorNoise
from air_sitl.state import GeoPoint

GPS_DENIAL_JSON = "gps_denial.json"  # the denial windows of a flight without a camera archive


def jsonable(value: Any) -> Any:
    """A JSON round trip, so that keys compare equal with what a marker file holds."""
    return json.loads(json.dumps(value, sort_keys=True, default=str))


def options_fields(options: FlightOptions) -> dict[str, Any]:
    """The flight options as a manifest records them."""
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
        # only when set, so that archives flown without it keep their manifests and run keys
        **({"altitude_offset_m": options.altitude_offset_m} if options.altitude_offset_m else {}),
        # likewise: --nav truth archives keep theirs; the onboard filter and its aid are inputs
        **({"nav": options.nav} if options.nav != "truth" else {}),
        **(
            {"nav_aid": options.nav_aid, "nav_aid_sigma_m": options.nav_aid_sigma_m}
            if options.nav_aid is not None
            else {}
        ),
    }


def sensor_noise_fields(scale: float) -> dict[str, Any]:
    """The sensor noise figures at ``scale`` (an infinite figure is null)."""
    noise = SensorNoise().scaled(scale)
    return {k: (v if math.isfinite(v) else None) for k, v in asdict(noise).items()}


def home_fields(home: GeoPoint) -> dict[str, float]:
    """Home as a manifest records it."""
    return {"lat_deg": home.lat_deg, "lon_deg": home.lon_deg, "alt_amsl_m": home.alt_amsl_m}


def gps_denial_record(windows: DenialWindows) -> list[dict[str, Any]]:
    """The denial windows as the archive records them (an open end is null)."""
    out = []
    for a, b in windows:
        end = None if b >= OPEN_END_NS else b
        out.append(
            {
                "start_ns": a,
                "end_ns": end,
                "start_s": a / NS_PER_S,
                "end_s": None if end is None else end / NS_PER_S,
            }
        )
    return out


def denial_fields(options: FlightOptions) -> dict[str, Any]:
    """``{"gps_denied": [...]}`` when the flight has GNSS denial windows, else nothing."""
    if not options.gps_denied_ns:
        return {}
    return {"gps_denied": gps_denial_record(options.gps_denied_ns)}


def manifest_inputs(options: FlightOptions, camera: CameraModel, home: GeoPoint) -> dict[str, Any]:
    """What every archive's manifest records of the software, home, flight and camera."""
    return {
        "software": {"name": "air-sitl", "version": __version__},
        "home": home_fields(home),
        "flight": options_fields(options),
        "sensor_noise": sensor_noise_fields(options.sensor_noise),
        "camera": camera_fields(camera),
    }


def archive_info_for(setup: FlightSetup, map_source: MapSource, *, plan_sha256: str) -> ArchiveInfo:
    """What a DatasetWriter needs besides the data: camera.yaml, the plan, manifest fields.

    ``run_key`` (the inputs that decide every byte) is what ``--resume`` compares.
    """
    camera = setup.camera
    assert camera is not None, "archive_info_for: the setup flies without a camera"
    options = setup.options
    map_info = jsonable(map_source.describe())
    if isinstance(map_info, dict) and "date" not in map_info:
        map_info["date"] = setup.map.date  # GeoTIFF dates are files: the one chosen, as asked
    if isinstance(map_info, dict) and setup.map.dem is not None:
        map_info["dem"] = setup.map.dem  # relief (issue 15); absent for flat maps, as before
    run_key = jsonable(
        {
            "plan_sha256": plan_sha256,
            "flight": options_fields(options),
            "map": map_info,
            "camera": camera_fields(camera),
            "software_version": __version__,
        }
    )
    manifest = {
        **manifest_inputs(options, camera, setup.home),
        "plan_sha256": plan_sha256,
        "map": map_info,
    }
    denial = denial_fields(options)
    return ArchiveInfo(
        scenario=setup.name,
        camera_yaml=camera_yaml_for(camera),
        plan_name=f"{setup.name}.plan",
        plan_text=plan_text(setup.mission),
        manifest={**jsonable(manifest), **denial},
        run_key={**run_key, **denial},
        nav_columns=options.nav == "ekf",
        agl_column=setup.map.dem is not None,
    )
