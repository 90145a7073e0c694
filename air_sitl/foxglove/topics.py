"""The Foxglove topics of one vehicle, built from the project's own types (the one home).

Topics under ``/air/<vehicle>/``: ``camera/image`` (CompressedImage, the archive's JPEG
bytes), ``camera/calibration`` (CameraCalibration), ``truth/fix``, ``gnss/fix``, ``nav/fix``,
``estimates/<name>/fix`` (LocationFix), ``camera/footprint`` and ``mission`` (GeoJSON),
``truth/pose``, ``nav/pose``, ``estimates/<name>/pose`` (PoseInFrame in ``map``), ``errors``
(JSON) and ``log`` (Log); ``/tf`` (FrameTransforms) is global. Frames are the ROS 2 view's
(REP 103/105): ``map`` ENU at home, ``base_link`` body FLU, ``camera_optical_frame``; every
timestamp is simulation time. :class:`Channels` logs them to a foxglove Context (a live server,
an MCAP writer or both).
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Sequence
from typing import Any

import foxglove
import numpy as np
import numpy.typing as npt
from foxglove.messages import (
    CameraCalibration,
    Color,
    CompressedImage,
    FrameTransform,
    FrameTransforms,
    GeoJson,
    LocationFix,
    LocationFixPositionCovarianceType,
    Log,
    LogLevel,
    Pose,
    PoseInFrame,
    Quaternion,
    Timestamp,
    Vector3,
)

from air_sitl.bus.ros2.messages import (
    BASE_FRAME,
    CAMERA_FRAME,
    MAP_FRAME,
    q_optical_to_flu_wxyz,
)
from air_sitl.camera.info import camera_yaml_dict
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.frames import LocalNed, q_flu_enu_to_frd_ned
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.state import GeoPoint, Quat, Vec3

TF_TOPIC = "/tf"
IMAGE = "camera/image"
CALIBRATION = "camera/calibration"
FOOTPRINT = "camera/footprint"
MISSION = "mission"
ERRORS = "errors"
LOG = "log"
TRUTH = "truth"
GNSS = "gnss"
NAV = "nav"

ERRORS_SCHEMA: dict[str, Any] = {
    "title": "air_sitl.Errors",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
        },
        "source": {"type": "string", "description": "nav or estimates/<name>"},
        "horizontal_m": {"type": "number"},
        "vertical_m": {"type": "number"},
    },
}

# RGBA per source (Map panel tracks): truth green, GNSS blue, filter orange; estimates cycle.
SOURCE_COLOURS: dict[str, tuple[float, float, float]] = {
    TRUTH: (0.1, 0.8, 0.2),
    GNSS: (0.2, 0.4, 1.0),
    NAV: (1.0, 0.55, 0.0),
}
ESTIMATE_COLOURS: tuple[tuple[float, float, float], ...] = (
    (0.9, 0.1, 0.1),
    (0.7, 0.2, 0.9),
    (0.0, 0.8, 0.8),
    (0.9, 0.8, 0.0),
    (0.9, 0.3, 0.6),
    (0.5, 0.3, 0.1),
)


def vehicle_topic(vehicle: str, name: str) -> str:
    """``/air/<vehicle>/<name>``."""
    return f"/air/{vehicle}/{name}"


def estimate_source(name: str) -> str:
    """The source (topic folder) of the estimator ``name``: ``estimates/<name>``."""
    return f"estimates/{name}"


def stamp(sim_time_ns: int) -> Timestamp:
    """A foxglove Timestamp of simulation nanoseconds."""
    sec, nsec = divmod(int(sim_time_ns), NS_PER_S)
    return Timestamp(sec=sec, nsec=nsec)


def _quat(q_wxyz: Quat) -> Quaternion:
    return Quaternion(x=q_wxyz[1], y=q_wxyz[2], z=q_wxyz[3], w=q_wxyz[0])


def image(sim_time_ns: int, jpeg: bytes) -> CompressedImage:
    """The camera frame, JPEG bytes as they are, in the optical frame."""
    return CompressedImage(
        timestamp=stamp(sim_time_ns), frame_id=CAMERA_FRAME, data=jpeg, format="jpeg"
    )


@functools.lru_cache(maxsize=8)
def _calibration_fields(camera: CameraModel) -> dict[str, Any]:
    """camera.yaml's intrinsics as CameraCalibration's fields (once per camera: the view sends
    them with every image)."""
    y = camera_yaml_dict(camera)
    return {
        "width": int(y["image_width"]),
        "height": int(y["image_height"]),
        "distortion_model": str(y["distortion_model"]),
        "D": [float(c) for c in y["distortion_coefficients"]["data"]],
        "K": [float(c) for c in y["camera_matrix"]["data"]],
        "R": [float(c) for c in y["rectification_matrix"]["data"]],
        "P": [float(c) for c in y["projection_matrix"]["data"]],
    }


def calibration(sim_time_ns: int, camera: CameraModel) -> CameraCalibration:
    """The intrinsics of camera.yaml (K, D, R, P as the ROS camera_info)."""
    return CameraCalibration(
        timestamp=stamp(sim_time_ns), frame_id=CAMERA_FRAME, **_calibration_fields(camera)
    )


def colour_of(source: str, estimate_index: int = 0) -> Color:
    """The track colour of a source (estimates: the n-th estimator's colour)."""
    rgb = SOURCE_COLOURS.get(source, ESTIMATE_COLOURS[estimate_index % len(ESTIMATE_COLOURS)])
    return Color(r=rgb[0], g=rgb[1], b=rgb[2], a=1.0)


def location_fix(
    sim_time_ns: int,
    geo: GeoPoint,
    colour: Color,
    *,
    cov_enu_m2: Sequence[float] | None = None,
    approximated: bool = False,
) -> LocationFix:
    """A fix of base_link; ``cov_enu_m2`` the 3x3 row-major position covariance (ENU)
    (``approximated``: diagonal only, as a receiver's eph/epv give it)."""
    if cov_enu_m2 is None:
        cov = [0.0] * 9
        kind = LocationFixPositionCovarianceType.Unknown
    else:
        cov = [float(c) for c in cov_enu_m2]
        kind = (
            LocationFixPositionCovarianceType.Approximated
            if approximated
            else LocationFixPositionCovarianceType.Known
        )
    return LocationFix(
        timestamp=stamp(sim_time_ns),
        frame_id=BASE_FRAME,
        latitude=geo.lat_deg,
        longitude=geo.lon_deg,
        altitude=geo.alt_amsl_m,
        position_covariance=cov,
        position_covariance_type=kind,
        color=colour,
    )


def diagonal_cov(std_h_m: float, std_v_m: float) -> list[float]:
    """The 3x3 covariance of a horizontal and a vertical standard deviation."""
    h2, v2 = std_h_m**2, std_v_m**2
    return [h2, 0.0, 0.0, 0.0, h2, 0.0, 0.0, 0.0, v2]


def pose(sim_time_ns: int, enu_m: Vec3, q_flu_enu_wxyz: Quat | None) -> PoseInFrame:
    """base_link in ``map`` (no attitude known: the identity, w = 1)."""
    q = q_flu_enu_wxyz if q_flu_enu_wxyz is not None else (1.0, 0.0, 0.0, 0.0)
    return PoseInFrame(
        timestamp=stamp(sim_time_ns),
        frame_id=MAP_FRAME,
        pose=Pose(position=Vector3(x=enu_m[0], y=enu_m[1], z=enu_m[2]), orientation=_quat(q)),
    )


def transforms(
    sim_time_ns: int, enu_m: Vec3, q_flu_enu_wxyz: Quat, camera: CameraModel | None
) -> FrameTransforms:
    """``map`` -> ``base_link`` (the truth) and ``base_link`` -> ``camera_optical_frame``."""
    t = stamp(sim_time_ns)
    out = [
        FrameTransform(
            timestamp=t,
            parent_frame_id=MAP_FRAME,
            child_frame_id=BASE_FRAME,
            translation=Vector3(x=enu_m[0], y=enu_m[1], z=enu_m[2]),
            rotation=_quat(q_flu_enu_wxyz),
        )
    ]
    if camera is not None:
        out.append(camera_mount(sim_time_ns, camera))
    return FrameTransforms(transforms=out)


def camera_mount(sim_time_ns: int, camera: CameraModel) -> FrameTransform:
    """``base_link`` -> ``camera_optical_frame`` (the mounting, no offset)."""
    return FrameTransform(
        timestamp=stamp(sim_time_ns),
        parent_frame_id=BASE_FRAME,
        child_frame_id=CAMERA_FRAME,
        translation=Vector3(x=0.0, y=0.0, z=0.0),
        rotation=_quat(_mount_wxyz(camera)),
    )


@functools.lru_cache(maxsize=8)
def _mount_wxyz(camera: CameraModel) -> Quat:
    return q_optical_to_flu_wxyz(camera)


@functools.lru_cache(maxsize=8)
def _corner_rays(camera: CameraModel) -> npt.NDArray[np.float64]:
    """The image corners' rays in the camera frame (columns: K^-1 (u, v, 1))."""
    w, h = camera.width_px - 1, camera.height_px - 1
    pixels = np.array([[0, w, w, 0], [0, 0, h, h], [1, 1, 1, 1]], dtype=np.float64)
    return np.asarray(np.linalg.inv(camera.intrinsics()) @ pixels, dtype=np.float64)


@functools.lru_cache(maxsize=8)
def _local(home: GeoPoint) -> LocalNed:
    return LocalNed(home.lat_deg, home.lon_deg, home.alt_amsl_m)


def footprint_lonlat(
    camera: CameraModel, enu_m: Vec3, q_flu_enu_wxyz: Quat, height_m: float, home: GeoPoint
) -> list[tuple[float, float]] | None:
    """The image corners on flat ground ``height_m`` below the camera, as (lon, lat); None
    when a corner looks at or above the horizon."""
    if not height_m > 0.0:
        return None
    rays = (camera.r_cam_to_ned(q_flu_enu_to_frd_ned(q_flu_enu_wxyz)) @ _corner_rays(camera)).T
    if not bool(np.all(rays[:, 2] > 1e-6)):
        return None
    local = _local(home)
    corners = []
    for ray in rays.tolist():
        s = height_m / ray[2]
        n, e = enu_m[1] + s * ray[0], enu_m[0] + s * ray[1]
        lat, lon, _ = local.to_geodetic(n, e, -enu_m[2] + height_m)
        corners.append((lon, lat))
    return corners


def footprint(corners_lonlat: list[tuple[float, float]]) -> GeoJson:
    """The camera's ground footprint as a closed GeoJSON polygon."""
    ring = [[lon, lat] for lon, lat in corners_lonlat]
    ring.append(ring[0])
    feature = {
        "type": "Feature",
        "geometry": {"type": "Polygon", "coordinates": [ring]},
        "properties": {"name": "camera footprint"},
    }
    return GeoJson(geojson=json.dumps({"type": "FeatureCollection", "features": [feature]}))


def _feature(geometry: dict[str, Any], **properties: Any) -> dict[str, Any]:
    return {"type": "Feature", "geometry": geometry, "properties": properties}


def mission_document(mission: Mission) -> dict[str, Any]:
    """The plan as a GeoJSON FeatureCollection: the route (LineString), each positioned item
    (Point, ``name`` "WP <seq>"), fence polygons and circles (Point with ``radius_m``)."""
    features: list[dict[str, Any]] = []
    route = [
        [it.lon_deg, it.lat_deg]
        for it in mission.items
        if it.is_nav and (it.lat_deg != 0.0 or it.lon_deg != 0.0)
    ]
    if len(route) >= 2:
        features.append(_feature({"type": "LineString", "coordinates": route}, name="route"))
    for k, it in enumerate(mission.items):
        if it.is_nav and (it.lat_deg != 0.0 or it.lon_deg != 0.0):
            point = {"type": "Point", "coordinates": [it.lon_deg, it.lat_deg]}
            features.append(_feature(point, name=f"WP {k}", alt_m=it.alt_m))
    vertex_cmds = (
        MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
    )
    circle_cmds = (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION)
    fence = list(mission.fence)
    k = 0
    while k < len(fence):
        it = fence[k]
        if it.command in vertex_cmds:
            n = max(int(it.param1), 1)
            ring = [[v.lon_deg, v.lat_deg] for v in fence[k : k + n]]
            ring.append(ring[0])
            kind = "inclusion" if it.command == vertex_cmds[0] else "exclusion"
            features.append(
                _feature({"type": "Polygon", "coordinates": [ring]}, name=f"fence {kind}")
            )
            k += n
            continue
        if it.command in circle_cmds:
            kind = "inclusion" if it.command == circle_cmds[0] else "exclusion"
            point = {"type": "Point", "coordinates": [it.lon_deg, it.lat_deg]}
            features.append(_feature(point, name=f"fence {kind}", radius_m=it.param1))
        k += 1
    return {"type": "FeatureCollection", "features": features}


def mission_geojson(mission: Mission) -> GeoJson:
    """:func:`mission_document` as a GeoJson message."""
    return GeoJson(geojson=json.dumps(mission_document(mission)))


def errors(sim_time_ns: int, source: str, truth_enu_m: Vec3, enu_m: Vec3) -> dict[str, Any]:
    """Horizontal and vertical error of a source against the truth (the ``errors`` topic)."""
    sec, nsec = divmod(int(sim_time_ns), NS_PER_S)
    return {
        "timestamp": {"sec": sec, "nsec": nsec},
        "source": source,
        "horizontal_m": math.hypot(enu_m[0] - truth_enu_m[0], enu_m[1] - truth_enu_m[1]),
        "vertical_m": abs(enu_m[2] - truth_enu_m[2]),
    }


def log(sim_time_ns: int, text: str, *, name: str, level: LogLevel = LogLevel.Info) -> Log:
    """A line of the ``log`` topic (mission events, the vehicle's STATUSTEXT)."""
    return Log(timestamp=stamp(sim_time_ns), level=level, message=text, name=name)


class Channels:
    """The channels of one vehicle on a foxglove Context, made on first use; counts messages."""

    def __init__(self, context: foxglove.Context, vehicle: str) -> None:
        self.context = context
        self.vehicle = vehicle
        self._channels: dict[str, foxglove.Channel] = {}
        self.counts: dict[str, int] = {}

    def topic(self, name: str) -> str:
        """The full topic of ``name`` (``/tf`` stays global)."""
        return name if name.startswith("/") else vehicle_topic(self.vehicle, name)

    def _channel(self, topic: str, schema: Any) -> foxglove.Channel:
        channel = self._channels.get(topic)
        if channel is None:
            if isinstance(schema, dict):
                channel = foxglove.Channel(topic, schema=schema, context=self.context)
            else:
                channel = foxglove.Channel(
                    topic, schema=schema, message_encoding="protobuf", context=self.context
                )
            self._channels[topic] = channel
        return channel

    def log(self, name: str, sim_time_ns: int, message: Any) -> None:
        """Log a well-known message (or a dict on ``errors``) at simulation time."""
        topic = self.topic(name)
        if isinstance(message, dict):
            self._channel(topic, ERRORS_SCHEMA).log(message, log_time=int(sim_time_ns))
        else:
            channel = self._channel(topic, message.get_schema())
            channel.log(message.encode(), log_time=int(sim_time_ns))
        self.counts[topic] = self.counts.get(topic, 0) + 1

    def close(self) -> None:
        """Close every channel."""
        for channel in self._channels.values():
            channel.close()
        self._channels.clear()
