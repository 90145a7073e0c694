"""ROS 2 messages of the simulation, and estimates out of ROS 2 messages (rosbags types).

Frames (REP 103/105): ``map`` is ENU with its origin at home, ``base_link`` is the body FLU
(x forward, y left, z up), ``camera_optical_frame`` is the camera's optical frame (x right,
y down, z along the optical axis), the frame our camera model renders in. Our own state is NED
and body FRD; the conversions live here and nowhere else. Header stamps are simulation time.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore
from rosbags.typesys.store import Typestore

from air_sitl.bus.codec import Estimate
from air_sitl.bus.ros2.options import DISTRO_NAMES
from air_sitl.camera.info import camera_yaml_dict, q_cam_to_body_wxyz
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.frames import (
    Q_FLU_TO_FRD,
    frd2flu,
    ned2enu,
    q_flu_enu_to_frd_ned,
    q_frd_ned_to_flu_enu,
    quat_conjugate,
    quat_multiply,
    quat_rotate,
)
from air_sitl.state import GpsFix, ImuSample, Quat, Vec3, VehicleState

MAP_FRAME = "map"
BASE_FRAME = "base_link"
CAMERA_FRAME = "camera_optical_frame"

DISTROS = {name: getattr(Stores, f"ROS2_{name.upper()}") for name in DISTRO_NAMES}

CLOCK = "rosgraph_msgs/msg/Clock"
IMU = "sensor_msgs/msg/Imu"
NAV_SAT_FIX = "sensor_msgs/msg/NavSatFix"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE_COV = "geometry_msgs/msg/PoseWithCovarianceStamped"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
TF = "tf2_msgs/msg/TFMessage"


def q_optical_to_flu_wxyz(camera: CameraModel) -> Quat:
    """The camera mount as a rotation: camera_optical_frame to base_link (FLU), scalar first."""
    return quat_multiply(Q_FLU_TO_FRD, q_cam_to_body_wxyz(camera))


def typestore(distro: str) -> Typestore:
    """The rosbags type store of a distro (its message definitions and type hashes)."""
    return get_typestore(DISTROS[distro])


class Messages:
    """Builds the messages of one vehicle with the types of one distro."""

    def __init__(self, store: Typestore) -> None:
        self.store = store
        t = store.types
        self._time = t["builtin_interfaces/msg/Time"]
        self._header = t["std_msgs/msg/Header"]
        self._vec = t["geometry_msgs/msg/Vector3"]
        self._point = t["geometry_msgs/msg/Point"]
        self._quat = t["geometry_msgs/msg/Quaternion"]
        self._pose = t["geometry_msgs/msg/Pose"]
        self._twist = t["geometry_msgs/msg/Twist"]
        self._t = t

    def hash(self, typename: str) -> str:
        """RIHS01 hash of a type in this distro."""
        return str(self.store.hash_rihs01(typename))

    def serialize(self, msg: Any, typename: str) -> bytes:
        """CDR (little-endian, with its encapsulation header)."""
        return bytes(self.store.serialize_cdr(msg, typename))

    def deserialize(self, payload: bytes, typename: str) -> Any:
        """A message of ``typename`` from CDR (with its header)."""
        return self.store.deserialize_cdr(payload, typename)

    def header(self, sim_time_ns: int, frame_id: str) -> Any:
        """A header stamped with simulation time."""
        return self._header(stamp=self.stamp(sim_time_ns), frame_id=frame_id)

    def stamp(self, sim_time_ns: int) -> Any:
        """builtin_interfaces/Time of simulation nanoseconds."""
        sec, nsec = divmod(sim_time_ns, NS_PER_S)
        return self._time(sec=sec, nanosec=nsec)

    def _q(self, q: Quat) -> Any:
        return self._quat(x=q[1], y=q[2], z=q[3], w=q[0])

    def _v(self, v: Vec3) -> Any:
        return self._vec(x=v[0], y=v[1], z=v[2])

    def clock(self, sim_time_ns: int) -> Any:
        """rosgraph_msgs/Clock."""
        return self._t[CLOCK](clock=self.stamp(sim_time_ns))

    def imu(self, imu: ImuSample) -> Any:
        """sensor_msgs/Imu in base_link: FLU rates and specific force, AHRS attitude in map."""
        unknown = np.zeros(9)
        return self._t[IMU](
            header=self.header(imu.sim_time_ns, BASE_FRAME),
            orientation=self._q(q_frd_ned_to_flu_enu(imu.q_ahrs_body_to_ned_wxyz)),
            orientation_covariance=unknown,
            angular_velocity=self._v(frd2flu(imu.gyro_frd_rad_s)),
            angular_velocity_covariance=unknown,
            linear_acceleration=self._v(frd2flu(imu.accel_frd_m_s2)),
            linear_acceleration_covariance=unknown,
        )

    def nav_sat_fix(self, sim_time_ns: int, fix: GpsFix | None) -> Any:
        """sensor_msgs/NavSatFix; ``fix`` None (GNSS denied or lost): status NO_FIX, NaN
        position. The altitude is our AMSL altitude (the simulation has no geoid)."""
        nav: Any = self._t[NAV_SAT_FIX]
        status_type: Any = self._t["sensor_msgs/msg/NavSatStatus"]
        service = status_type.SERVICE_GPS
        if fix is None or fix.fix_type < 2:
            return nav(
                header=self.header(sim_time_ns, BASE_FRAME),
                status=status_type(status=status_type.STATUS_NO_FIX, service=service),
                latitude=math.nan,
                longitude=math.nan,
                altitude=math.nan,
                position_covariance=np.zeros(9),
                position_covariance_type=nav.COVARIANCE_TYPE_UNKNOWN,
            )
        h2, v2 = fix.eph_m**2, fix.epv_m**2
        return nav(
            header=self.header(fix.sim_time_ns, BASE_FRAME),
            status=status_type(status=status_type.STATUS_FIX, service=service),
            latitude=fix.lat_deg,
            longitude=fix.lon_deg,
            altitude=fix.alt_amsl_m,
            position_covariance=np.array([h2, 0, 0, 0, h2, 0, 0, 0, v2], dtype=np.float64),
            position_covariance_type=nav.COVARIANCE_TYPE_APPROXIMATED,
        )

    def odometry(self, state: VehicleState) -> Any:
        """nav_msgs/Odometry of the truth: base_link in map, twist in base_link."""
        q = state.q_body_to_ned_wxyz
        v_frd = quat_rotate(quat_conjugate(q), state.vel_ned_m_s)
        zeros = np.zeros(36)
        cov_type = self._t["geometry_msgs/msg/PoseWithCovariance"]
        twist_cov = self._t["geometry_msgs/msg/TwistWithCovariance"]
        e, n, u = ned2enu(state.pos_ned_m)
        return self._t[ODOMETRY](
            header=self.header(state.sim_time_ns, MAP_FRAME),
            child_frame_id=BASE_FRAME,
            pose=cov_type(
                pose=self._pose(
                    position=self._point(x=e, y=n, z=u),
                    orientation=self._q(q_frd_ned_to_flu_enu(q)),
                ),
                covariance=zeros,
            ),
            twist=twist_cov(
                twist=self._twist(
                    linear=self._v(frd2flu(v_frd)),
                    angular=self._v(frd2flu(state.rate_frd_rad_s)),
                ),
                covariance=zeros,
            ),
        )

    def compressed_image(self, sim_time_ns: int, jpeg: bytes) -> Any:
        """sensor_msgs/CompressedImage (JPEG) in the camera's optical frame."""
        return self._t[COMPRESSED_IMAGE](
            header=self.header(sim_time_ns, CAMERA_FRAME),
            format="jpeg",
            data=np.frombuffer(jpeg, dtype=np.uint8),
        )

    def camera_info(self, sim_time_ns: int, camera: CameraModel) -> Any:
        """sensor_msgs/CameraInfo of camera.yaml (the same intrinsics, distortion, R, P)."""
        y = camera_yaml_dict(camera)
        roi = self._t["sensor_msgs/msg/RegionOfInterest"]
        return self._t[CAMERA_INFO](
            header=self.header(sim_time_ns, CAMERA_FRAME),
            height=int(y["image_height"]),
            width=int(y["image_width"]),
            distortion_model=str(y["distortion_model"]),
            d=np.array(y["distortion_coefficients"]["data"], dtype=np.float64),
            k=np.array(y["camera_matrix"]["data"], dtype=np.float64),
            r=np.array(y["rectification_matrix"]["data"], dtype=np.float64),
            p=np.array(y["projection_matrix"]["data"], dtype=np.float64),
            binning_x=0,
            binning_y=0,
            roi=roi(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
        )

    def camera_mount(self, sim_time_ns: int, camera: CameraModel) -> Any:
        """tf2_msgs/TFMessage: base_link -> camera_optical_frame (the mounting, no offset)."""
        q_opt_to_flu = q_optical_to_flu_wxyz(camera)
        stamped = self._t["geometry_msgs/msg/TransformStamped"]
        transform = self._t["geometry_msgs/msg/Transform"]
        tf = stamped(
            header=self.header(sim_time_ns, BASE_FRAME),
            child_frame_id=CAMERA_FRAME,
            transform=transform(
                translation=self._v((0.0, 0.0, 0.0)), rotation=self._q(q_opt_to_flu)
            ),
        )
        return self._t[TF](transforms=[tf])


def estimate_of(msg: Any, typename: str) -> Estimate:
    """Our estimate of an Odometry or PoseWithCovarianceStamped: the pose of base_link in
    ``map`` (ENU from home) at the header's stamp (the frame's exposure time); the pose
    covariance's position block becomes ``cov_enu_m2``. ValueError on anything else."""
    header = msg.header
    if header.frame_id not in ("", MAP_FRAME):
        err = f"{typename}: frame_id {header.frame_id!r}, expected {MAP_FRAME!r} (ENU, home)"
        raise ValueError(err)
    pose = msg.pose.pose
    cov = np.asarray(msg.pose.covariance, dtype=np.float64).reshape(6, 6)
    p, o = pose.position, pose.orientation
    enu = (float(p.x), float(p.y), float(p.z))
    q = (float(o.w), float(o.x), float(o.y), float(o.z))
    norm = math.sqrt(sum(c * c for c in q))
    if not all(math.isfinite(c) for c in (*enu, *q)):
        err = f"{typename}: non-finite position or orientation"
        raise ValueError(err)
    q_ned = None if norm < 1e-9 else q_flu_enu_to_frd_ned(tuple(c / norm for c in q))  # type: ignore[arg-type]
    block = cov[:3, :3]
    cov_enu = None
    if np.all(np.isfinite(block)) and np.all(np.diag(block) > 0):
        cov_enu = tuple(float(c) for c in block.ravel())
    stamp = header.stamp
    return Estimate(
        frame=None,
        sim_time_ns=int(stamp.sec) * NS_PER_S + int(stamp.nanosec),
        enu_m=enu,
        geo=None,
        q_body_to_ned_wxyz=q_ned,
        cov_enu_m2=cov_enu,
    )
