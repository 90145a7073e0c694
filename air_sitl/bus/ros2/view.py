"""The ROS 2 view of one vehicle (``--ros2``): node ``air_sitl_<vehicle>`` beside our own keys.

Publishers (topics relative to ``--ros-namespace``, ``/clock`` and ``/tf_static`` global):
``air/<vehicle>/camera/image/compressed`` (JPEG), ``air/<vehicle>/camera/camera_info`` (with
every image, same stamp and frame), ``air/<vehicle>/imu``, ``air/<vehicle>/gnss/fix`` (NO_FIX
while no fix comes: GNSS denied), ``air/<vehicle>/truth/odometry`` (``--publish-truth``),
``/clock`` and ``/tf_static`` (the camera mount, transient-local).

Subscriptions: ``air/<vehicle>/estimates/<name>`` (nav_msgs/Odometry or
geometry_msgs/PoseWithCovarianceStamped of any name) become estimates on our own key
``air/<vehicle>/estimate/<name>``, so the estimate log, ``--nav-aid`` and ``--wait-for`` take
them as they take any estimator's. Samples of other types, of unknown hashes, without a valid
attachment or that do not decode are counted and dropped.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.ros2.layout import (
    Durability,
    Qos,
    dds_type_name,
    decode_attachment,
    ros_name_token,
)
from air_sitl.bus.ros2.messages import (
    CAMERA_INFO,
    CLOCK,
    COMPRESSED_IMAGE,
    IMU,
    NAV_SAT_FIX,
    ODOMETRY,
    POSE_COV,
    TF,
    Messages,
    estimate_of,
    typestore,
)
from air_sitl.bus.ros2.node import Ros2Node
from air_sitl.bus.ros2.options import Ros2Options
from air_sitl.bus.session import Bus, Message, Publisher
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import CameraFrame, SimSample

GNSS_PERIOD_NS = NS_PER_S // 5  # until two fixes tell the receiver's rate
ESTIMATE_TYPES = (ODOMETRY, POSE_COV)
STATIC = Qos(durability=Durability.TRANSIENT_LOCAL, depth=1)


def node_name(vehicle: str) -> str:
    """``air_sitl_<vehicle>`` (the vehicle must be a ROS 2 name token)."""
    return f"air_sitl_{ros_name_token('--vehicle (for --ros2)', vehicle)}"


def open_node(bus: Bus, options: Ros2Options, keys: KeySpace, suffix: str = "") -> Ros2Node:
    """The vehicle's node on ``bus`` (``air_sitl_<vehicle><suffix>``)."""
    name = node_name(keys.vehicle) + suffix
    return Ros2Node(bus, options, name, Messages(typestore(options.distro)))


class Ros2View(NullSink):
    """A :class:`~air_sitl.sinks.Sink` publishing the simulation as ROS 2 messages."""

    def __init__(
        self,
        node: Ros2Node,
        keys: KeySpace,
        *,
        camera: CameraModel | None,
        publish_truth: bool,
        imu_rate_hz: float,
        block_frames: bool = False,
    ) -> None:
        self.node = node
        self.msgs = node.messages
        ns = node.options.resolve
        root = f"air/{keys.vehicle}"
        self._clock = node.publisher("/clock", CLOCK)
        self._imu = node.publisher(ns(f"{root}/imu"), IMU)
        self._fix = node.publisher(ns(f"{root}/gnss/fix"), NAV_SAT_FIX)
        self._truth = None
        if publish_truth:
            self._truth = node.publisher(ns(f"{root}/truth/odometry"), ODOMETRY)
        self.cam = None if camera is None else Ros2Camera(node, keys, camera, block=block_frames)
        self._warm_up()
        self._imu_every = max(1, round(200.0 / max(imu_rate_hz, 1e-9)))
        self._step = 0
        self._last_fix_ns: int | None = None
        self._last_no_fix_ns: int | None = None
        self._gnss_period_ns: int | None = None  # learnt from the fixes

    def _warm_up(self) -> None:
        """Serialize one message of each type now: rosbags compiles a type's serializer on
        its first use (tens of ms), which would otherwise delay the first samples."""
        m = self.msgs
        m.serialize(m.clock(0), CLOCK)
        m.serialize(m.nav_sat_fix(0, None), NAV_SAT_FIX)

    @property
    def image_matched(self) -> bool:
        """True when a subscriber listens to the image topic."""
        return self.cam is not None and self.cam.image.matched

    def on_sample(self, sample: SimSample) -> None:
        """Clock every step, IMU decimated, NavSatFix (NO_FIX when fixes stop), truth."""
        m = self.msgs
        t = sample.state.sim_time_ns
        self._clock.publish(m.serialize(m.clock(t), CLOCK))
        if self._step % self._imu_every == 0:
            self._imu.publish(m.serialize(m.imu(sample.imu), IMU))
        self._step += 1
        fix = sample.gps
        if fix is not None:
            if self._last_fix_ns is not None and fix.sim_time_ns > self._last_fix_ns:
                # The receiver's period is the shortest gap (a denial makes longer ones).
                gap = fix.sim_time_ns - self._last_fix_ns
                self._gnss_period_ns = min(gap, self._gnss_period_ns or gap)
            self._last_fix_ns = fix.sim_time_ns
            self._fix.publish(m.serialize(m.nav_sat_fix(t, fix), NAV_SAT_FIX))
        elif self._no_fix_due(t):
            self._last_no_fix_ns = t
            self._fix.publish(m.serialize(m.nav_sat_fix(t, None), NAV_SAT_FIX))
        if self._truth is not None:
            self._truth.publish(m.serialize(m.odometry(sample.state), ODOMETRY))

    def _no_fix_due(self, t: int) -> bool:
        """No fix for one and a half periods, and no NO_FIX for one period."""
        period = self._gnss_period_ns or GNSS_PERIOD_NS
        fix, no_fix = self._last_fix_ns, self._last_no_fix_ns
        overdue = fix is None or t - fix >= period + period // 2
        return overdue and (no_fix is None or t - no_fix >= period)

    def on_frame(self, frame: CameraFrame) -> None:
        """Publish the frame unless lockstep already did."""
        self.publish_frame(frame)

    def publish_frame(self, frame: CameraFrame) -> None:
        """CompressedImage and CameraInfo of one frame (once per frame index)."""
        if self.cam is not None:
            self.cam.publish(frame.index, frame.sim_time_ns, frame.jpeg)

    @property
    def frames_published(self) -> int:
        """Frames put on the image topic."""
        return 0 if self.cam is None else self.cam.frames_published

    def close(self, result: FlightResult) -> None:
        """Nothing buffered."""


class Ros2Camera:
    """The camera's topics: CompressedImage and CameraInfo of each frame (same stamp, same
    frame_id), and the mount on ``/tf_static`` (transient-local: late subscribers get it)."""

    def __init__(
        self, node: Ros2Node, keys: KeySpace, camera: CameraModel, *, block: bool = False
    ) -> None:
        self.msgs = m = node.messages
        self.camera = camera
        root = node.options.resolve(f"air/{keys.vehicle}/camera")
        self.image = node.publisher(f"{root}/image/compressed", COMPRESSED_IMAGE, block=block)
        self._info = node.publisher(f"{root}/camera_info", CAMERA_INFO)
        # Kept: its cache answers late subscribers while the publisher lives.
        self._tf_static = node.publisher("/tf_static", TF, STATIC)
        self._tf_static.publish(m.serialize(m.camera_mount(0, camera), TF))
        m.serialize(m.compressed_image(0, b""), COMPRESSED_IMAGE)  # compile the serializers
        m.serialize(m.camera_info(0, camera), CAMERA_INFO)
        self._last_frame = -1
        self._lock = threading.Lock()
        self.frames_published = 0

    def publish(self, index: int, sim_time_ns: int, jpeg: bytes) -> None:
        """One frame (each index once: lockstep may have published it already)."""
        with self._lock:
            if index <= self._last_frame:
                return
            self._last_frame = index
        m = self.msgs
        # The image first (as image_transport's CameraPublisher does): it is what waits.
        self.image.publish(m.serialize(m.compressed_image(sim_time_ns, jpeg), COMPRESSED_IMAGE))
        self._info.publish(m.serialize(m.camera_info(sim_time_ns, self.camera), CAMERA_INFO))
        self.frames_published += 1


class Ros2Estimates:
    """ROS 2 estimators' poses on ``air/<vehicle>/estimates/<name>``, re-put as our estimates.

    ``announce``: estimator names whose subscription tokens are declared up front (those the
    flight waits for or fuses); estimates of any name are taken.
    """

    def __init__(self, node: Ros2Node, keys: KeySpace, announce: Iterable[str] = ()) -> None:
        self.node = node
        self.keys = keys
        opts = node.options
        self._topic_root = opts.resolve(f"air/{keys.vehicle}/estimates")
        prefix = f"{opts.domain_id}/{self._topic_root.strip('/')}/"
        self._prefix = prefix
        self._by_key_type = {
            f"{dds_type_name(t)}/{node.messages.hash(t)}": t for t in ESTIMATE_TYPES
        }
        self._out: dict[str, Publisher] = {}
        self._lock = threading.Lock()
        self.accepted = 0
        self.rejected = 0
        self.first_error: str | None = None
        self._announced: set[str] = set()
        for name in announce:
            self.announce(name)
        node.bus.subscribe(f"{prefix}*/*/*", self._on_message)

    def announce(self, name: str) -> None:
        """Declare the subscription token of the estimator ``name`` (Odometry), once."""
        if name not in self._announced:
            self._announced.add(name)
            self.node.announce_subscription(f"{self._topic_root}/{name}", ODOMETRY)

    def _reject(self, error: str) -> None:
        with self._lock:
            self.rejected += 1
            self.first_error = self.first_error or error

    def _on_message(self, message: Message) -> None:
        name, _, type_and_hash = message.key[len(self._prefix) :].partition("/")
        typename = self._by_key_type.get(type_and_hash)
        if typename is None:
            self._reject(f"{message.key}: not an Odometry or PoseWithCovarianceStamped hash")
            return
        try:
            decode_attachment(message.attachment)
            msg = self.node.messages.deserialize(message.payload, typename)
            est = estimate_of(msg, typename)
        except Exception as err:  # a payload of the wrong layout raises anything
            self._reject(f"{message.key}: {type(err).__name__}: {err}")
            return
        payload = codec.encode_estimate(
            sim_time_ns=est.sim_time_ns,
            enu_m=est.enu_m,
            q_body_to_ned_wxyz=est.q_body_to_ned_wxyz,
            cov_enu_m2=est.cov_enu_m2,
        )
        with self._lock:
            pub = self._out.get(name)
            if pub is None:
                pub = self.node.bus.publisher(
                    self.keys.estimate(name), encoding=codec.JSON_ENCODING, block=True
                )
                self._out[name] = pub
            self.accepted += 1
        pub.put(payload)
