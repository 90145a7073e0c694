"""``--ros2``: the vehicle as a ROS 2 node, checked by a peer written from rmw_zenoh's design
document alone (tests/bus/ros2_peer.py, no air_sitl ROS 2 code): discovery through liveliness
tokens, data on the documented keys, every attachment, every payload decoded by rosbags."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml
import zenoh
import zenoh.ext
from short_plans import write_short_plan

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.session import BusConfig, Message, open_bus

from .helpers import (
    HOME,
    WAIT_SAFETY,
    cli,
    free_endpoint,
    make_sample,
    start,
    stop,
    wait_for_line,
    wait_until,
)
from .ros2_peer import (
    CDR_LE_HEADER,
    STORE,
    RosPeer,
    data_key,
    dds_name,
    gid,
    read_attachment,
)

pytestmark = pytest.mark.integration

NODE = "air_sitl_uav0"
TOPICS = {
    "/air/uav0/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/air/uav0/camera/camera_info": "sensor_msgs/msg/CameraInfo",
    "/air/uav0/imu": "sensor_msgs/msg/Imu",
    "/air/uav0/gnss/fix": "sensor_msgs/msg/NavSatFix",
    "/air/uav0/truth/odometry": "nav_msgs/msg/Odometry",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf_static": "tf2_msgs/msg/TFMessage",
}


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_short_plan(tmp_path_factory.mktemp("plan") / "R2.plan", HOME, leg_m=40.0)


def fly(plan: Path, out: Path, endpoint: str, *extra: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        cli("fly", str(plan), "--out", str(out), "--air-start", "--quiet", "--ros2",
            "--zenoh-connect", endpoint, *extra),
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def ns_of(stamp: Any) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def rotate(q: Any, v: tuple[float, float, float]) -> np.ndarray:
    """v rotated by the geometry_msgs Quaternion q."""
    w, x, y, z = q.w, q.x, q.y, q.z
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])  # fmt: skip
    return r @ np.array(v)


def test_a_ros2_subscriber_discovers_and_decodes_every_topic(plan: Path, tmp_path: Path) -> None:
    endpoint = free_endpoint()
    peer = RosPeer(listen=(endpoint,))
    late: list[Any] = []
    tf_key = data_key(0, "/tf_static", TOPICS["/tf_static"])
    clock_key = data_key(0, "/clock", TOPICS["/clock"])
    late_tf: list[bytes] = []

    def join_late() -> None:
        # A transient-local subscriber that joins after /tf_static went out still gets it.
        if wait_until(lambda: len(peer.received(clock_key)) > 10):
            late.append(zenoh.ext.declare_advanced_subscriber(
                peer.session, tf_key, lambda s: late_tf.append(s.payload.to_bytes()),
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True),
            ))  # fmt: skip

    joiner = threading.Thread(target=join_late)
    joiner.start()
    out = tmp_path / "a"
    wall_start = time.time_ns()
    try:
        run = fly(plan, out, endpoint, "--publish-truth", "--gps-denied-window", "1:2.4",
                  "--gps-denied-window", "3:4")  # fmt: skip
        wall_end = time.time_ns()
        joiner.join()
        assert run.returncode == 0, run.stderr
        wait_until(lambda: bool(late_tf), 10.0)
    finally:
        for sub in late:
            sub.undeclare()
        peer.close()

    # Discovery: the node, and one publisher per topic with its type, hash and QoS.
    nodes = [t for t in peer.tokens if t.kind == "NN" and t.node == NODE]
    assert len(nodes) == 1 and nodes[0].namespace == "/" and nodes[0].enclave == "/", peer.tokens
    pubs = {t.topic: t for t in peer.tokens if t.kind == "MP" and t.node == NODE}
    assert set(pubs) == set(TOPICS), sorted(pubs)
    for topic, typename in TOPICS.items():
        token = pubs[topic]
        assert token.zid == nodes[0].zid and token.namespace == "/"
        assert token.type == dds_name(typename)
        assert token.type_hash == STORE.hash_rihs01(typename)
    assert pubs["/tf_static"].qos.split(":")[1] == "1"  # transient local
    assert pubs["/air/uav0/imu"].qos.split(":")[1] == ""  # volatile (the default)

    # Every sample: on a documented key, with a valid attachment from its publisher, CDR.
    # Publishers drop under congestion (as rmw_zenoh's keep-last ones: a slow subscriber, here
    # on a loaded machine, loses samples): a lost sample leaves a gap in the sequence numbers,
    # which otherwise count 1, 2, 3 ... Every sample that arrived is checked.
    decoded: dict[str, list[Any]] = {}
    seq_of: dict[str, list[int]] = {}
    for topic, typename in TOPICS.items():
        key = data_key(0, topic, typename)
        got = peer.received(key)
        assert got, topic
        want_gid = gid(pubs[topic].key)
        seqs = []
        for s in got:
            assert s.attachment is not None, topic
            seq, stamp, sender = read_attachment(s.attachment)
            assert sender == want_gid, topic
            assert wall_start <= stamp <= wall_end, topic
            seqs.append(seq)
            assert s.payload[:4] == CDR_LE_HEADER
        assert seqs == sorted(set(seqs)) and seqs[0] >= 1, topic
        seq_of[topic] = seqs
        decoded[topic] = [STORE.deserialize_cdr(s.payload, typename) for s in got]
    assert {s.key.split("/", 1)[0] for s in peer.samples} == {"0"}

    # /clock: simulation time, every 5 ms; every header stamp is one of its instants.
    clock = [ns_of(m.clock) for m in decoded["/clock"]]
    assert [t - 5_000_000 * s for t, s in zip(clock, seq_of["/clock"], strict=True)] == [
        clock[0] - 5_000_000 * seq_of["/clock"][0]
    ] * len(clock)
    instants = set(range(clock[0] - 5_000_000 * seq_of["/clock"][0], clock[-1] + 1, 5_000_000))

    # Images: the archive's JPEGs, in the camera's optical frame; camera_info beside them.
    images = decoded["/air/uav0/camera/image/compressed"]
    infos = decoded["/air/uav0/camera/camera_info"]
    meta = read_csv(out / "metadata.csv")
    image_seqs = seq_of["/air/uav0/camera/image/compressed"]
    assert len(images) >= 10 and image_seqs[-1] <= len(meta) >= 50
    rows = [meta[s - 1] for s in image_seqs]  # sample n is frame n - 1
    for m, row in zip(images, rows, strict=True):
        assert m.format == "jpeg"
        assert m.data.tobytes() == (out / row["Filename"]).read_bytes()
        assert m.header.frame_id == "camera_optical_frame"
        assert ns_of(m.header.stamp) in instants
    info_stamps = dict(zip(seq_of["/air/uav0/camera/camera_info"], infos, strict=True))
    for m, seq in zip(images, image_seqs, strict=True):
        if seq in info_stamps:
            assert ns_of(info_stamps[seq].header.stamp) == ns_of(m.header.stamp)
    cam = yaml.safe_load((out / "camera.yaml").read_text())
    info = infos[0]
    assert info.header.frame_id == images[0].header.frame_id
    assert (info.width, info.height) == (cam["image_width"], cam["image_height"])
    assert list(info.k) == pytest.approx(cam["camera_matrix"]["data"])
    assert list(info.p) == pytest.approx(cam["projection_matrix"]["data"])
    assert info.distortion_model == "plumb_bob"

    # Truth odometry: base_link in map (ENU from home) = the archive's pose at each frame.
    truth = {ns_of(m.header.stamp): m for m in decoded["/air/uav0/truth/odometry"]}
    assert all(m.header.frame_id == "map" and m.child_frame_id == "base_link"
               for m in truth.values())  # fmt: skip
    for m, row in zip(images, rows, strict=True):
        if ns_of(m.header.stamp) not in truth:
            continue  # dropped under congestion
        p = truth[ns_of(m.header.stamp)].pose.pose.position
        assert (p.x, p.y, p.z) == pytest.approx(
            (float(row["PoseX"]), float(row["PoseY"]), float(row["PoseZ"])), abs=1e-3
        )
    # FLU/ENU: flying east, the nose (base_link +x) points east and the velocity is forward.
    mid = decoded["/air/uav0/truth/odometry"][len(truth) // 2]
    nose = rotate(mid.pose.pose.orientation, (1.0, 0.0, 0.0))
    assert nose[0] > 0.95, nose
    assert mid.twist.twist.linear.x > 10.0

    # IMU: in base_link, simulation time, the AHRS attitude close to the truth's.
    imus = decoded["/air/uav0/imu"]
    assert all(m.header.frame_id == "base_link" and ns_of(m.header.stamp) in instants
               for m in imus)  # fmt: skip
    for m in imus[::50]:
        t = truth.get(ns_of(m.header.stamp))
        if t is None:
            continue
        a = rotate(m.orientation, (1.0, 0.0, 0.0))
        b = rotate(t.pose.pose.orientation, (1.0, 0.0, 0.0))
        assert float(a @ b) > math.cos(math.radians(5.0))
        assert m.linear_acceleration.z > 5.0  # FLU: the specific force of lift points up

    # GNSS: NO_FIX inside the denial windows (still published at the fix rate), fixes outside.
    fixes = decoded["/air/uav0/gnss/fix"]
    no_fix = [ns_of(m.header.stamp) for m in fixes if m.status.status == -1]
    fixed = [ns_of(m.header.stamp) for m in fixes if m.status.status >= 0]
    windows = ((1e9, 2.4e9), (3e9, 4e9))
    for a, b in windows:
        assert [t for t in no_fix if a <= t < b], no_fix
        assert not [t for t in fixed if a <= t < b]
    assert all(any(a <= t < b for a, b in windows) for t in no_fix), no_fix
    assert [t for t in fixed if t < 1e9] and [t for t in fixed if t >= 4e9]
    assert all(math.isnan(m.latitude) for m in fixes if m.status.status == -1)

    # TF: the camera mount; the optical axis points down, image right along the right wing.
    (tf_msg,) = decoded["/tf_static"]
    (tf,) = tf_msg.transforms
    assert (tf.header.frame_id, tf.child_frame_id) == ("base_link", "camera_optical_frame")
    assert rotate(tf.transform.rotation, (0.0, 0.0, 1.0)) == pytest.approx([0, 0, -1], abs=1e-9)
    assert rotate(tf.transform.rotation, (1.0, 0.0, 0.0)) == pytest.approx([0, -1, 0], abs=1e-9)
    assert late_tf, "a late transient-local subscriber got no /tf_static"
    assert STORE.deserialize_cdr(late_tf[0], TOPICS["/tf_static"]).transforms[0].child_frame_id == (
        "camera_optical_frame"
    )
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ros2"]["frames_published"] == len(meta)


ODOM = "nav_msgs/msg/Odometry"
IMAGE_TOPIC = "/air/uav0/camera/image/compressed"
POSE = "geometry_msgs/msg/PoseWithCovarianceStamped"
IMAGE_KEY = data_key(
    0, "/air/uav0/camera/image/compressed", TOPICS["/air/uav0/camera/image/compressed"]
)
TRUTH_KEY = data_key(0, "/air/uav0/truth/odometry", ODOM)


class TruthVo:
    """An estimator node: answers every image with the truth pose at the image's stamp (as
    nav_msgs/Odometry in map, covariance 2 m), the way a VO node copies the image header."""

    def __init__(self, peer: RosPeer, name: str) -> None:
        peer.declare_node(f"vo_{name}")
        self.pub = peer.declare_publisher(f"/air/uav0/estimates/{name}", ODOM)
        self.truth: dict[int, Any] = {}
        self.waiting: list[Any] = []
        self.sent = 0
        self.lock = threading.Lock()
        peer.listeners.append(self.on_sample)

    def on_sample(self, s: Any) -> None:
        if s.key == TRUTH_KEY:
            m = STORE.deserialize_cdr(s.payload, ODOM)
            with self.lock:
                self.truth[ns_of(m.header.stamp)] = m
        elif s.key == IMAGE_KEY:
            m = STORE.deserialize_cdr(s.payload, TOPICS["/air/uav0/camera/image/compressed"])
            with self.lock:
                self.waiting.append(m.header)
        else:
            return
        with self.lock:
            # The truth of the frame's instant, or (lost under congestion on a loaded machine)
            # the latest one before it, 5 ms and about 8 cm per step earlier.
            latest = max(self.truth, default=-1)
            ready = [h for h in self.waiting if ns_of(h.stamp) <= latest]
            self.waiting = [h for h in self.waiting if ns_of(h.stamp) > latest]
            for header in ready:
                before = [t for t in self.truth if t <= ns_of(header.stamp)]
                truth = self.truth[max(before) if before else min(self.truth)]
                truth.header.stamp = header.stamp
                truth.pose.covariance = np.diag([4.0, 4.0, 4.0, 0.1, 0.1, 0.1]).ravel()
                self.pub.publish(bytes(STORE.serialize_cdr(truth, ODOM)))
                self.sent += 1


def test_a_ros2_estimator_aids_the_flight_under_denial_in_lockstep(
    plan: Path, tmp_path: Path
) -> None:
    endpoint = free_endpoint()
    peer = RosPeer(listen=(endpoint,))
    vo = TruthVo(peer, "rosvo")
    out = tmp_path / "a"
    try:
        run = fly(plan, out, endpoint, "--publish-truth", "--wait-for", "rosvo",
                  "--nav-aid", "rosvo", "--gps-denied-after", "1", *WAIT_SAFETY)  # fmt: skip
    finally:
        peer.close()
    assert run.returncode == 0, run.stderr
    meta = read_csv(out / "metadata.csv")
    rows = read_csv(out / "estimates" / "rosvo.csv")
    n = len(meta)
    assert n >= 50 and [int(r["frame"]) for r in rows] == list(range(n))
    for r, m in zip(rows, meta, strict=True):
        assert (float(r["east_m"]), float(r["north_m"]), float(r["up_m"])) == pytest.approx(
            (float(m["PoseX"]), float(m["PoseY"]), float(m["PoseZ"])), abs=2.0
        )
        assert r["latency_frames"] == "0"  # lockstep: frame k+1 waited for k
    summary = json.loads((out / "summary.json").read_text())
    assert summary["estimates"] == {"rosvo": n}
    assert summary["ros2"]["estimates_accepted"] == vo.sent
    assert summary["ros2"]["estimates_rejected"] == 0
    aid = summary["nav"]["aid"]
    # In lockstep the filter takes the estimate of frame k once frame k + 1 is out: the last
    # ones come after the flight.
    assert aid["name"] == "rosvo" and vo.sent - 2 <= aid["received"] <= vo.sent
    assert aid["fused"] > 0.8 * vo.sent
    assert summary["nav"]["gnss_denied_s"] > 3.0
    assert summary["nav"]["horizontal_error_denied_m"]["max"] < 5.0
    subs = [t for t in peer.tokens if t.kind == "MS" and t.node == NODE]
    assert [(t.topic, t.type) for t in subs] == [("/air/uav0/estimates/rosvo", dds_name(ODOM))]


def test_bad_ros2_estimates_are_counted_and_ignored(plan: Path, tmp_path: Path) -> None:
    endpoint = free_endpoint()
    peer = RosPeer(listen=(endpoint,))
    peer.declare_node("bad_vo")
    good = peer.declare_publisher("/air/uav0/estimates/vo", POSE)
    odom = peer.declare_publisher("/air/uav0/estimates/vo", ODOM)
    # The same Odometry on a key with another type hash (another distro's definition).
    wrong_key = odom.key.rsplit("/", 1)[0] + "/RIHS01_" + "0" * 64
    wrong = peer.session.declare_publisher(wrong_key)
    sent = threading.Event()

    def on_sample(s: Any) -> None:
        if s.key != IMAGE_KEY or sent.is_set():
            return
        sent.set()
        header = STORE.deserialize_cdr(
            s.payload, TOPICS["/air/uav0/camera/image/compressed"]
        ).header
        header.frame_id = "map"
        types = STORE.types
        pose = types[POSE](header=header, pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)),
            covariance=np.zeros(36)))  # fmt: skip
        odometry = STORE.deserialize_cdr(
            bytes(STORE.serialize_cdr(types[ODOM](
                header=header, child_frame_id="base_link", pose=pose.pose,
                twist=types["geometry_msgs/msg/TwistWithCovariance"](
                    twist=types["geometry_msgs/msg/Twist"](
                        linear=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0),
                        angular=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)),
                    covariance=np.zeros(36))), ODOM)), ODOM)  # fmt: skip
        odom_cdr = bytes(STORE.serialize_cdr(odometry, ODOM))
        odom.publish(b"\x00\x01\x00\x00garbage")  # not an Odometry
        wrong.put(odom_cdr, attachment=b"")  # unknown type hash
        odom.publish(odom_cdr, with_attachment=False)  # no attachment
        good.publish(bytes(STORE.serialize_cdr(pose, POSE)))

    peer.listeners.append(on_sample)
    out = tmp_path / "a"
    try:
        run = fly(plan, out, endpoint)
    finally:
        peer.close()
    assert run.returncode == 0, run.stderr
    assert sent.is_set()
    assert "3 ROS 2 estimate sample(s) ignored" in run.stderr, run.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ros2"]["estimates_rejected"] == 3
    assert summary["ros2"]["estimates_accepted"] == 1
    rows = read_csv(out / "estimates" / "vo.csv")
    assert [(r["east_m"], r["north_m"], r["up_m"]) for r in rows] == [
        ("1.0000", "2.0000", "3.0000")
    ]
    assert summary["capture_frames"] == len(read_csv(out / "metadata.csv")) >= 50


def test_camera_bridge_publishes_its_frames_as_ros2(tmp_path: Path) -> None:
    sim_ep, bridge_ep = free_endpoint(), free_endpoint()
    sim = open_bus(BusConfig(listen=(sim_ep,), connect=(), serves=True))
    frames: list[Message] = []
    sim.subscribe(KeySpace().image, frames.append)
    bridge = start(cli("camera-bridge", "--map", "urban", "--ros2", "--zenoh-listen", bridge_ep,
                       "--zenoh-connect", sim_ep))  # fmt: skip
    peer = RosPeer(connect=(bridge_ep,))
    try:
        wait_for_line(bridge, "serving")
        pub = BusPublisher(sim, PublishOptions(publish_truth=True, home=HOME))
        assert wait_until(lambda: pub._truth is not None and pub._truth.matched)
        image_key = data_key(0, "/air/uav0/camera/image/compressed", TOPICS[IMAGE_TOPIC])
        assert wait_until(lambda: any(t.topic == IMAGE_TOPIC for t in peer.tokens))
        # 200 Hz physics, a camera exposure every 4th step (50 Hz): frames 0..9.
        samples = [
            make_sample(i * 5_000_000, east_m=0.075 * i, frame=None if i % 4 else i // 4)
            for i in range(40)
        ]
        for s in samples:
            pub.on_sample(s)
        assert wait_until(lambda: len(peer.received(image_key)) == 10 and len(frames) == 10)
    finally:
        code, _, err = stop(bridge)
        peer.close()
        sim.close()
    assert code == 0, err
    nodes = {t.node for t in peer.tokens if t.kind == "NN"}
    assert "air_sitl_uav0_camera" in nodes
    ours = {codec.decode_frame_meta(m.attachment).sim_time_ns: m.payload for m in frames}
    for s in peer.received(image_key):
        assert s.attachment is not None and read_attachment(s.attachment)[0] >= 1
        m = STORE.deserialize_cdr(s.payload, TOPICS[IMAGE_TOPIC])
        assert m.data.tobytes() == ours[ns_of(m.header.stamp)]


def test_ros2_nodes_reach_the_vehicle_through_a_router(plan: Path, tmp_path: Path) -> None:
    # rmw_zenoh's topology: every node a peer connected to one router (air-sitl router here),
    # which tells each the others' endpoints; data then flows peer to peer.
    endpoint = free_endpoint()
    router = start(cli("router", "--listen", endpoint))
    try:
        wait_for_line(router, "listening")
        peer = RosPeer(connect=(endpoint,))
        try:
            run = fly(plan, tmp_path / "a", endpoint)
            assert run.returncode == 0, run.stderr
            image_key = data_key(0, IMAGE_TOPIC, TOPICS[IMAGE_TOPIC])
            n = len(read_csv(tmp_path / "a" / "metadata.csv"))
            assert n >= 50 and wait_until(lambda: len(peer.received(image_key)) >= 10, 10.0)
            assert NODE in {t.node for t in peer.tokens if t.kind == "NN"}
        finally:
            peer.close()
    finally:
        code, _, err = stop(router)
    assert code == 0, err


def test_serve_is_a_ros2_node_too(plan: Path) -> None:
    endpoint = free_endpoint()
    peer = RosPeer(listen=(endpoint,))
    imu_key = data_key(0, "/air/srv/imu", TOPICS["/air/uav0/imu"])
    serve = start(cli("serve", "--plan", str(plan), "--zenoh-connect", endpoint, "--ros2",
                      "--vehicle", "srv", "--mavlink", "udpin:127.0.0.1:0", "--speed", "4",
                      "--quiet"))  # fmt: skip
    try:
        assert wait_until(lambda: len(peer.received(imu_key)) > 50)
    finally:
        code, _out, err = stop(serve)
        peer.close()
    assert code == 0, err
    assert "air_sitl_srv" in {t.node for t in peer.tokens if t.kind == "NN"}
    imu = STORE.deserialize_cdr(peer.received(imu_key)[-1].payload, TOPICS["/air/uav0/imu"])
    assert imu.header.frame_id == "base_link"
    assert imu.linear_acceleration.z == pytest.approx(9.8, abs=0.5)  # on the ground: 1 g up
