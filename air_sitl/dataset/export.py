"""Export an archive as ROS bags (rosbag2 MCAP, rosbag1) or TUM trajectories for evo.

The only module that imports ``rosbags``. Topics as AIR's ROS node published them, stamped
with simulation time: ``/camera/image/compressed`` (jpeg), ``/camera/camera_info``, ``/imu``
(our archives: raw IMU at the physics rate with the AHRS orientation; AIR's: the Imu
quaternion per frame), ``/gps`` (NavSatFix, altitude = RelativeAltitude as AIR's node did),
``/gt_pose`` (PoseStamped, ENU), ``/map_location`` and ``/svo_location`` (PointStamped).
Frames: ``map`` is ENU relative to home, ``base_link`` is body FLU, ``camera`` the optical frame.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from air_sitl.dataset.air_schema import (
    ESTIMATES_DIR,
    IMU_COLUMNS,
    IMU_CSV,
)
from air_sitl.dataset.estimates import parse_estimates
from air_sitl.dataset.manifest import manifest_home
from air_sitl.dataset.reader import Archive
from air_sitl.errors import DatasetError
from air_sitl.frames import q_frd_ned_to_flu_enu, wxyz2xyzw
from air_sitl.state import Quat

TOPIC_IMAGE = "/camera/image/compressed"
TOPIC_CAMERA_INFO = "/camera/camera_info"
TOPIC_IMU = "/imu"
TOPIC_GPS = "/gps"
TOPIC_GT_POSE = "/gt_pose"
TOPIC_MAP = "/map_location"
TOPIC_SVO = "/svo_location"

TYPES = {
    TOPIC_IMAGE: "sensor_msgs/msg/CompressedImage",
    TOPIC_CAMERA_INFO: "sensor_msgs/msg/CameraInfo",
    TOPIC_IMU: "sensor_msgs/msg/Imu",
    TOPIC_GPS: "sensor_msgs/msg/NavSatFix",
    TOPIC_GT_POSE: "geometry_msgs/msg/PoseStamped",
    TOPIC_MAP: "geometry_msgs/msg/PointStamped",
    TOPIC_SVO: "geometry_msgs/msg/PointStamped",
}


@dataclass(frozen=True, slots=True)
class Message:
    """One message to write: topic, timestamp (ns of simulation time), typed fields."""

    topic: str
    stamp_ns: int
    fields: dict[str, Any]


def _camera_fields(archive: Archive) -> dict[str, Any]:
    cam = archive.camera()
    if cam is None:
        w, h, hfov = 640, 480, 57.0  # AIR's camera (SPEC section 1)
        f = (w / 2.0) / math.tan(math.radians(hfov) / 2.0)
        k = [f, 0.0, w / 2.0, 0.0, f, h / 2.0, 0.0, 0.0, 1.0]
        p = [f, 0.0, w / 2.0, 0.0, 0.0, f, h / 2.0, 0.0, 0.0, 0.0, 1.0, 0.0]
        return {"width": w, "height": h, "k": k, "p": p, "d": [0.0] * 5}
    try:
        return {
            "width": int(cam["image_width"]),
            "height": int(cam["image_height"]),
            "k": [float(x) for x in cam["camera_matrix"]["data"]],
            "p": [float(x) for x in cam["projection_matrix"]["data"]],
            "d": [float(x) for x in cam["distortion_coefficients"]["data"]],
        }
    except (KeyError, TypeError, ValueError) as err:
        msg = f"{archive.path}/camera.yaml: missing or bad field ({err})"
        raise DatasetError(msg) from None


def _imu_rows(archive: Archive) -> Iterator[list[str]]:
    if not archive.exists(IMU_CSV):
        return
    text = archive.read_bytes(IMU_CSV).decode("ascii")
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    reader = csv.reader(text.splitlines())
    header = next(reader, None)
    if header is None or tuple(header) != IMU_COLUMNS:
        msg = f"{archive.path}/{IMU_CSV}: header is not {','.join(IMU_COLUMNS)}"
        raise DatasetError(msg)
    yield from reader


def archive_messages(archive: Archive) -> Iterator[Message]:
    """Every message of the archive in time order (frames interleaved with IMU samples)."""
    cam = _camera_fields(archive)
    frame_msgs: list[Message] = []
    for k, row in enumerate(archive.rows):
        t = archive.timestamp_ns(k)
        frame_msgs.append(Message(TOPIC_IMAGE, t, {"format": "jpeg", "index": k}))
        frame_msgs.append(Message(TOPIC_CAMERA_INFO, t, cam))
        frame_msgs.append(
            Message(
                TOPIC_GPS,
                t,
                {"lat": row.lat_deg, "lon": row.lon_deg, "alt": row.rel_alt_m},
            )
        )
        frame_msgs.append(
            Message(
                TOPIC_GT_POSE,
                t,
                {"position": row.pose_enu_m, "orientation_xyzw": row.orientation_xyzw},
            )
        )
        frame_msgs.append(
            Message(
                TOPIC_MAP, t, {"point": (float(row.map_xy_px[0]), float(row.map_xy_px[1]), 0.0)}
            )
        )
        if all(math.isfinite(c) for c in row.svo_enu_m):
            frame_msgs.append(Message(TOPIC_SVO, t, {"point": row.svo_enu_m}))
        if archive.kind == "air":
            frame_msgs.append(Message(TOPIC_IMU, t, {"orientation_xyzw": row.imu_xyzw}))
    imu_msgs: list[Message] = []
    for fields in _imu_rows(archive):
        v = [float(x) for x in fields[1:]]
        q_enu = q_frd_ned_to_flu_enu((v[6], v[7], v[8], v[9]))
        imu_msgs.append(
            Message(
                TOPIC_IMU,
                int(fields[0]),
                {
                    "orientation_xyzw": wxyz2xyzw(q_enu),
                    # Body FRD -> FLU: y and z change sign.
                    "gyro_flu": (v[0], -v[1], -v[2]),
                    "accel_flu": (v[3], -v[4], -v[5]),
                },
            )
        )
    # Stable merge by time: frame messages first at equal stamps.
    merged = sorted(
        [(m.stamp_ns, 0, i, m) for i, m in enumerate(frame_msgs)]
        + [(m.stamp_ns, 1, i, m) for i, m in enumerate(imu_msgs)],
        key=lambda x: (x[0], x[1], x[2]),
    )
    for _, _, _, m in merged:
        yield m


class _Builder:
    """Builds rosbags message objects for one typestore (ROS1 and ROS2 differ in details)."""

    def __init__(self, ros1: bool) -> None:
        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        self.t = self.store.types
        self.seq: dict[str, int] = {}

    def serialize(self, msg: Any, msgtype: str) -> bytes:
        if self.ros1:
            return bytes(self.store.serialize_ros1(msg, msgtype))
        return bytes(self.store.serialize_cdr(msg, msgtype))

    def header(self, topic: str, stamp_ns: int, frame_id: str) -> Any:
        stamp = self.t["builtin_interfaces/msg/Time"](
            sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000
        )
        if self.ros1:
            seq = self.seq.get(topic, 0)
            self.seq[topic] = seq + 1
            return self.t["std_msgs/msg/Header"](seq=seq, stamp=stamp, frame_id=frame_id)
        return self.t["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def vec3(self, v: tuple[float, float, float]) -> Any:
        return self.t["geometry_msgs/msg/Vector3"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def point(self, v: tuple[float, float, float]) -> Any:
        return self.t["geometry_msgs/msg/Point"](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def quat(self, q: Quat) -> Any:
        return self.t["geometry_msgs/msg/Quaternion"](
            x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3])
        )

    def build(self, m: Message, jpeg: Callable[[int], bytes]) -> Any:
        t = self.t
        f = m.fields
        if m.topic == TOPIC_IMAGE:
            data = np.frombuffer(jpeg(int(f["index"])), dtype=np.uint8)
            return t[TYPES[m.topic]](
                header=self.header(m.topic, m.stamp_ns, "camera"), format="jpeg", data=data
            )
        if m.topic == TOPIC_CAMERA_INFO:
            roi = t["sensor_msgs/msg/RegionOfInterest"](
                x_offset=0, y_offset=0, height=0, width=0, do_rectify=False
            )
            arrays = {
                "d": np.array(f["d"], dtype=np.float64),
                "k": np.array(f["k"], dtype=np.float64),
                "r": np.eye(3, dtype=np.float64).reshape(9),
                "p": np.array(f["p"], dtype=np.float64),
            }
            if self.ros1:
                arrays = {k.upper(): v for k, v in arrays.items()}
            return t[TYPES[m.topic]](
                header=self.header(m.topic, m.stamp_ns, "camera"),
                height=f["height"],
                width=f["width"],
                distortion_model="plumb_bob",
                binning_x=0,
                binning_y=0,
                roi=roi,
                **arrays,
            )
        if m.topic == TOPIC_IMU:
            unknown = np.zeros(9, dtype=np.float64)
            none = np.zeros(9, dtype=np.float64)
            none[0] = -1.0  # REP-145: this quantity is not provided
            gyro = f.get("gyro_flu")
            accel = f.get("accel_flu")
            return t[TYPES[m.topic]](
                header=self.header(m.topic, m.stamp_ns, "base_link"),
                orientation=self.quat(f["orientation_xyzw"]),
                orientation_covariance=unknown,
                angular_velocity=self.vec3(gyro or (0.0, 0.0, 0.0)),
                angular_velocity_covariance=unknown if gyro else none,
                linear_acceleration=self.vec3(accel or (0.0, 0.0, 0.0)),
                linear_acceleration_covariance=unknown if accel else none,
            )
        if m.topic == TOPIC_GPS:
            status = t["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
            return t[TYPES[m.topic]](
                header=self.header(m.topic, m.stamp_ns, "base_link"),
                status=status,
                latitude=float(f["lat"]),
                longitude=float(f["lon"]),
                altitude=float(f["alt"]),
                position_covariance=np.zeros(9, dtype=np.float64),
                position_covariance_type=0,
            )
        if m.topic == TOPIC_GT_POSE:
            pose = t["geometry_msgs/msg/Pose"](
                position=self.point(f["position"]), orientation=self.quat(f["orientation_xyzw"])
            )
            return t[TYPES[m.topic]](header=self.header(m.topic, m.stamp_ns, "map"), pose=pose)
        # /map_location and /svo_location
        frame_id = "map_image" if m.topic == TOPIC_MAP else "map"
        return t[TYPES[m.topic]](
            header=self.header(m.topic, m.stamp_ns, frame_id), point=self.point(f["point"])
        )


def check_out(out: Path) -> None:
    """DatasetError unless ``out`` is new and its folder exists (nothing is overwritten)."""
    if out.exists():
        msg = f"{out}: exists already (choose another output; nothing is overwritten)"
        raise DatasetError(msg)
    if not out.parent.is_dir():
        msg = f"{out.parent}: no such folder for the output"
        raise DatasetError(msg)


def export_rosbag(
    archive: Archive,
    out: Path,
    *,
    ros1: bool,
    progress: Callable[[int, int], None] | None = None,
) -> dict[str, int]:
    """Write every message of ``archive`` to a rosbag2 (MCAP) folder or a rosbag1 file;
    ``progress(frames written, frames)`` hears every 50th frame and the last."""
    check_out(out)
    total = len(archive.rows)
    builder = _Builder(ros1)
    counts: dict[str, int] = {}
    writer: Any = (
        Writer1(out) if ros1 else Writer2(out, version=9, storage_plugin=StoragePlugin.MCAP)
    )
    try:
        writer.open()
    except OSError as err:
        msg = f"{out}: cannot create the bag: {err.strerror}"
        raise DatasetError(msg) from None
    try:
        conns: dict[str, Any] = {}
        for topic, msgtype in TYPES.items():
            conns[topic] = writer.add_connection(topic, msgtype, typestore=builder.store)
        for m in archive_messages(archive):
            msg = builder.build(m, archive.jpeg)
            writer.write(conns[m.topic], m.stamp_ns, builder.serialize(msg, TYPES[m.topic]))
            counts[m.topic] = counts.get(m.topic, 0) + 1
            if progress is not None and m.topic == TOPIC_IMAGE:
                done = counts[m.topic]
                if done % 50 == 0 or done == total:
                    progress(done, total)
    except OSError as err:
        msg = f"{out}: cannot write the bag: {err.strerror}"
        raise DatasetError(msg) from None
    finally:
        writer.close()
    return counts


def tum_lines(archive: Archive, estimate: str | None = None) -> list[str]:
    """TUM lines ``t x y z qx qy qz qw`` (s, ENU m): ground truth, or the estimator's positions.

    ``estimate`` names ``estimates/<name>.csv``; ``svo`` without such a file takes AIR's Svo
    columns. Estimates without orientation get the identity quaternion (use evo's
    translation-only alignment for them).
    """
    lines: list[str] = []
    if estimate is None:
        for k, row in enumerate(archive.rows):
            x, y, z = row.pose_enu_m
            qx, qy, qz, qw = row.orientation_xyzw
            t = archive.timestamp_ns(k) / 1e9
            lines.append(f"{t:.9f} {x:.4f} {y:.4f} {z:.4f} {qx:.9f} {qy:.9f} {qz:.9f} {qw:.9f}")
        return lines
    name = f"{ESTIMATES_DIR}/{estimate}.csv"
    if not archive.exists(name):
        if estimate.lower() == "svo":
            for k, row in enumerate(archive.rows):
                if all(math.isfinite(c) for c in row.svo_enu_m):
                    x, y, z = row.svo_enu_m
                    t = archive.timestamp_ns(k) / 1e9
                    lines.append(f"{t:.9f} {x:.4f} {y:.4f} {z:.4f} 0 0 0 1")
            return lines
        msg = f"{archive.path}/{name}: no such estimate in the archive"
        raise DatasetError(msg)
    try:
        text = archive.read_bytes(name).decode("utf-8")
    except UnicodeDecodeError as err:
        msg = f"{archive.path}/{name}: not UTF-8 text ({err})"
        raise DatasetError(msg) from None
    for p in parse_estimates(text, f"{archive.path}/{name}", manifest_home(archive.manifest)):
        if p.sim_time_ns is not None:
            t_ns = p.sim_time_ns
        elif p.frame is not None and 0 <= p.frame < len(archive.rows):
            t_ns = archive.timestamp_ns(p.frame)
        else:
            continue
        x, y, z = p.enu_m
        q = (0.0, 0.0, 0.0, 1.0)
        if p.q_body_to_ned_wxyz is not None:
            q = wxyz2xyzw(q_frd_ned_to_flu_enu(p.q_body_to_ned_wxyz))
        lines.append(
            f"{t_ns / 1e9:.9f} {x:.4f} {y:.4f} {z:.4f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}"
        )
    return lines


def export_tum(archive: Archive, out: Path, estimate: str | None = None) -> int:
    """Write a TUM trajectory file; returns the number of poses."""
    lines = tum_lines(archive, estimate)
    try:
        out.write_text("".join(line + "\n" for line in lines), encoding="ascii")
    except OSError as err:
        msg = f"{out}: cannot write: {err.strerror}"
        raise DatasetError(msg) from None
    return len(lines)
