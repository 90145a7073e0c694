"""Message encoding of the bus (pure: no zenoh, no I/O).

One encoding: every small message is a UTF-8 JSON object carrying ``"v"`` (the contract
version) and ``"sim_time_ns"``; camera frames are the raw JPEG bytes with a JSON attachment
(``FrameMeta``). Floats go through ``json`` (shortest round-trip repr), so a decoded
``VehicleState`` is bit-identical to the one encoded: the remote camera renders the same image.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, fields
from typing import Any

from air_sitl.bus.estimate_contract import check_estimate
from air_sitl.bus.keys import CONTRACT_VERSION
from air_sitl.errors import BusError
from air_sitl.files import parse_json_object
from air_sitl.state import AutopilotStatus, GeoPoint, GpsFix, ImuSample, Quat, Vec3, VehicleState

JSON_ENCODING = "application/json"
JPEG_ENCODING = "image/jpeg"

_STATE_FIELDS = tuple(f.name for f in fields(VehicleState))
# Fields with a default (the surface under the aircraft, --dem): sent only when set, so flights
# without relief publish what they did before.
_OPTIONAL_STATE_FIELDS = frozenset(f.name for f in fields(VehicleState) if f.default is None)
# json.dumps(..., separators=...) builds a new encoder on every call (its cached one is for the
# default separators only): one encoder, the same bytes, 15-30 % less a message.
_ENCODER = json.JSONEncoder(separators=(",", ":"))


def dumps(message: dict[str, Any]) -> bytes:
    """Compact JSON bytes with the contract version first."""
    return _ENCODER.encode({"v": CONTRACT_VERSION, **message}).encode()


def loads(payload: bytes, what: str) -> dict[str, Any]:
    """Parse one JSON object; BusError naming ``what`` when it is not one."""
    return parse_json_object(payload, what, BusError)


@contextmanager
def fields_of(what: str, noun: str = "message") -> Iterator[None]:
    """Turn a missing or malformed field read inside into one BusError line naming ``what``."""
    try:
        yield
    except (KeyError, TypeError, ValueError, IndexError) as err:
        msg = f"{what}: bad {noun} ({err!r})"
        raise BusError(msg) from None


def decode_geo(value: Any) -> GeoPoint:
    """A WGS84 point ``{lat_deg, lon_deg, alt_amsl_m}`` (a home, an estimate); KeyError,
    TypeError or ValueError when it is not one (read it inside :func:`fields_of`)."""
    return GeoPoint(**{k: float(value[k]) for k in ("lat_deg", "lon_deg", "alt_amsl_m")})


def encode_imu(imu: ImuSample) -> bytes:
    """``imu``: gyro (rad/s), specific force (m/s^2), both FRD; AHRS quaternion body->NED."""
    return dumps(
        {
            "sim_time_ns": imu.sim_time_ns,
            "gyro_frd_rad_s": imu.gyro_frd_rad_s,
            "accel_frd_m_s2": imu.accel_frd_m_s2,
            "q_ahrs_body_to_ned_wxyz": imu.q_ahrs_body_to_ned_wxyz,
        }
    )


def decode_imu(payload: bytes) -> ImuSample:
    """Inverse of :func:`encode_imu`."""
    m = loads(payload, "imu")
    with fields_of("imu"):
        return ImuSample(
            sim_time_ns=int(m["sim_time_ns"]),
            gyro_frd_rad_s=_vec3(m["gyro_frd_rad_s"]),
            accel_frd_m_s2=_vec3(m["accel_frd_m_s2"]),
            q_ahrs_body_to_ned_wxyz=_quat(m["q_ahrs_body_to_ned_wxyz"]),
        )


def encode_gps(fix: GpsFix) -> bytes:
    """``gps``: WGS84 position, altitude AMSL, NED velocity, fix quality."""
    return dumps(
        {
            "sim_time_ns": fix.sim_time_ns,
            "lat_deg": fix.lat_deg,
            "lon_deg": fix.lon_deg,
            "alt_amsl_m": fix.alt_amsl_m,
            "vel_ned_m_s": fix.vel_ned_m_s,
            "fix_type": fix.fix_type,
            "satellites": fix.satellites,
            "eph_m": fix.eph_m,
            "epv_m": fix.epv_m,
        }
    )


def encode_state(state: VehicleState) -> dict[str, Any]:
    """Every VehicleState field under its own name (tuples become lists; an optional field
    only when it is set)."""
    out = {name: getattr(state, name) for name in _STATE_FIELDS}
    for name in _OPTIONAL_STATE_FIELDS:
        if out[name] is None:
            del out[name]
    return out


def decode_state(m: dict[str, Any], what: str = "truth") -> VehicleState:
    """A VehicleState from :func:`encode_state` output (exact float round trip)."""
    try:
        values: dict[str, Any] = {
            name: m.get(name) if name in _OPTIONAL_STATE_FIELDS else m[name]
            for name in _STATE_FIELDS
        }
    except KeyError as err:
        msg = f"{what}: missing field {err.args[0]!r}"
        raise BusError(msg) from None
    for name, value in values.items():
        if isinstance(value, list):
            values[name] = tuple(float(x) for x in value)
    values["sim_time_ns"] = int(values["sim_time_ns"])
    values["on_ground"] = bool(values["on_ground"])
    return VehicleState(**values)


def encode_truth(state: VehicleState, frame: int | None) -> bytes:
    """``truth``: the full VehicleState; ``frame``: the capture index at camera ticks, else null."""
    return dumps({**encode_state(state), "frame": frame})


def encode_clock(sim_time_ns: int) -> bytes:
    """``clock``: simulation time."""
    return dumps({"sim_time_ns": sim_time_ns})


def encode_status(sim_time_ns: int, status: AutopilotStatus, home: GeoPoint | None) -> bytes:
    """``mission/status``: mode, armed, mission item, capture window, home."""
    return dumps(
        {
            "sim_time_ns": sim_time_ns,
            "mode": status.mode.value,
            "armed": status.armed,
            "current_seq": status.current_seq,
            "capturing": status.capturing,
            "mission_completed": status.mission_completed,
            "home": None
            if home is None
            else {"lat_deg": home.lat_deg, "lon_deg": home.lon_deg, "alt_amsl_m": home.alt_amsl_m},
        }
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraInfo:
    """What ``camera/info`` tells a client: pinhole intrinsics, size, rate, mounting."""

    width_px: int
    height_px: int
    hfov_deg: float
    rate_hz: float
    q_cam_to_body_wxyz: Quat  # camera (x right, y down the image, z optical axis) -> body FRD

    @property
    def focal_px(self) -> float:
        """fx = fy = (W/2) / tan(HFOV/2)."""
        return (self.width_px / 2.0) / math.tan(math.radians(self.hfov_deg) / 2.0)


def encode_camera_info(info: CameraInfo) -> bytes:
    """``camera/info``: intrinsics (fx, fy, cx, cy in pixels), size, FOV, rate, mounting."""
    f = info.focal_px
    return dumps(
        {
            "width_px": info.width_px,
            "height_px": info.height_px,
            "hfov_deg": info.hfov_deg,
            "fx_px": f,
            "fy_px": f,
            "cx_px": (info.width_px - 1) / 2.0,  # pixel centres at integer coordinates
            "cy_px": (info.height_px - 1) / 2.0,
            "rate_hz": info.rate_hz,
            "q_cam_to_body_wxyz": info.q_cam_to_body_wxyz,
            "distortion": None,
        }
    )


def decode_camera_info(payload: bytes) -> CameraInfo:
    """Inverse of :func:`encode_camera_info`."""
    m = loads(payload, "camera/info")
    with fields_of("camera/info"):
        return CameraInfo(
            width_px=int(m["width_px"]),
            height_px=int(m["height_px"]),
            hfov_deg=float(m["hfov_deg"]),
            rate_hz=float(m["rate_hz"]),
            q_cam_to_body_wxyz=_quat(m["q_cam_to_body_wxyz"]),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class FrameMeta:
    """The attachment of a ``camera/image`` sample (the payload is the JPEG itself)."""

    frame: int
    sim_time_ns: int
    width_px: int
    height_px: int
    map_xy_px: tuple[int, int] | None = None  # only in camera-bridge render replies
    # Share of the image showing map nodata or ground off the map: only in render replies
    # (CameraFrame.nodata_fraction, what the local camera measures).
    nodata_fraction: float | None = None


def encode_frame_meta(meta: FrameMeta) -> bytes:
    """Attachment JSON of a frame."""
    m: dict[str, Any] = {
        "frame": meta.frame,
        "sim_time_ns": meta.sim_time_ns,
        "width_px": meta.width_px,
        "height_px": meta.height_px,
    }
    if meta.map_xy_px is not None:
        m["map_xy_px"] = meta.map_xy_px
    if meta.nodata_fraction is not None:
        m["nodata_fraction"] = meta.nodata_fraction
    return dumps(m)


def decode_frame_meta(attachment: bytes | None) -> FrameMeta:
    """Inverse of :func:`encode_frame_meta`."""
    if attachment is None:
        msg = "camera/image: sample has no attachment (frame index and time)"
        raise BusError(msg)
    m = loads(attachment, "camera/image attachment")
    with fields_of("camera/image attachment", "value"):
        xy = m.get("map_xy_px")
        nodata = m.get("nodata_fraction")
        return FrameMeta(
            frame=int(m["frame"]),
            sim_time_ns=int(m["sim_time_ns"]),
            width_px=int(m["width_px"]),
            height_px=int(m["height_px"]),
            map_xy_px=None if xy is None else (int(xy[0]), int(xy[1])),
            nodata_fraction=None if nodata is None else float(nodata),
        )


@dataclass(frozen=True, slots=True, kw_only=True)
class Estimate:
    """One position estimate received from ``estimate/<name>``.

    At least one of ``frame`` / ``sim_time_ns`` is set. No position (or ``null`` coordinates)
    is an answer saying "no estimate for this frame": it still counts in lockstep.
    """

    frame: int | None
    sim_time_ns: int | None
    enu_m: Vec3 | None  # east, north, up relative to home
    geo: GeoPoint | None
    q_body_to_ned_wxyz: Quat | None = None
    cov_enu_m2: tuple[float, ...] | None = None  # 3x3 row-major
    fix: bool | None = None  # a map fix accepted at this frame (None: the estimator does not say)


def encode_estimate(
    *,
    frame: int | None = None,
    sim_time_ns: int | None = None,
    enu_m: Vec3 | None = None,
    geo: GeoPoint | None = None,
    q_body_to_ned_wxyz: Quat | None = None,
    cov_enu_m2: tuple[float, ...] | None = None,
    fix: bool | None = None,
) -> bytes:
    """What an estimator publishes on ``estimate/<name>`` (clients may write the JSON by hand)."""
    m: dict[str, Any] = {}
    if frame is not None:
        m["frame"] = frame
    if sim_time_ns is not None:
        m["sim_time_ns"] = sim_time_ns
    if enu_m is not None:
        m["enu_m"] = enu_m
    if geo is not None:
        m.update(lat_deg=geo.lat_deg, lon_deg=geo.lon_deg, alt_amsl_m=geo.alt_amsl_m)
    if q_body_to_ned_wxyz is not None:
        m["q_body_to_ned_wxyz"] = q_body_to_ned_wxyz
    if cov_enu_m2 is not None:
        m["cov_enu_m2"] = cov_enu_m2
    if fix is not None:
        m["fix"] = fix
    return dumps(m)


def decode_estimate(payload: bytes, what: str) -> Estimate:
    """Parse and check an estimate against the contract; EstimateRejectedError (a BusError) with
    the reason and a one-line message when it is unusable (:mod:`.estimate_contract`)."""
    f = check_estimate(payload, what)
    return Estimate(
        frame=f["frame"],
        sim_time_ns=f["sim_time_ns"],
        enu_m=f["enu_m"],
        geo=f["geo"],
        q_body_to_ned_wxyz=f["q"],
        cov_enu_m2=f["cov"],
        fix=f["fix"],
    )


def _vec3(value: Any) -> Vec3:
    x, y, z = (float(v) for v in value)
    return (x, y, z)


def _quat(value: Any) -> Quat:
    w, x, y, z = (float(v) for v in value)
    return (w, x, y, z)
