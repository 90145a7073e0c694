"""rmw_zenoh's layout as air-sitl writes it, against the examples of rmw_zenoh's design
document and zenoh-ext's own serializer; the ROS 2 options' user errors; where namespace and
domain id put the node and its topics."""

from __future__ import annotations

from pathlib import Path

import pytest
import zenoh
import zenoh.ext
from cli_errors import one_line_error
from rosbags.typesys import Stores, get_typestore
from short_plans import write_short_plan

from air_sitl.bus.keys import KeySpace
from air_sitl.bus.ros2.layout import (
    Durability,
    Entity,
    Qos,
    Reliability,
    decode_attachment,
    encode_attachment,
    endpoint_token,
    gid_of,
    node_token,
    topic_key,
)
from air_sitl.bus.ros2.messages import Messages, estimate_of, typestore
from air_sitl.bus.ros2.options import Ros2Options
from air_sitl.bus.ros2.view import Ros2View, open_node
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.frames import q_flu_enu_to_frd_ned as frd_to_ned
from air_sitl.frames import q_frd_ned_to_flu_enu as flu_to_enu

from .helpers import HOME, free_endpoint, make_sample, wait_until
from .ros2_peer import STORE, RosPeer, data_key

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"


def test_keys_and_tokens_read_as_the_design_document_examples() -> None:
    store = get_typestore(Stores.ROS2_KILTED)
    assert store.hash_rihs01("std_msgs/msg/String") == STRING_HASH
    assert topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH) == (
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    )
    assert topic_key(0, "/robot1/chatter", "std_msgs/msg/String", STRING_HASH).startswith(
        "0/robot1/chatter/std_msgs::msg::dds_::String_/"
    )
    zid = "aac3178e146ba6f1fc6e6a4085e77f21"
    assert node_token(0, zid, 0, "/", "listener") == f"@ros2_lv/0/{zid}/0/0/NN/%/%/listener"
    token = endpoint_token(
        Entity.PUBLISHER, domain_id=0, zid=zid, node_id=0, entity_id=10, namespace="/",
        node="talker", topic="/chatter", typename="std_msgs/msg/String",
        type_hash=STRING_HASH, qos=Qos(depth=7),
    )  # fmt: skip
    assert token == (
        f"@ros2_lv/0/{zid}/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/"
        f"{STRING_HASH}/::,7:,:,:,,"
    )
    assert Qos(Reliability.BEST_EFFORT, Durability.TRANSIENT_LOCAL, 42).keyexpr() == "2:1:,:,:,:,,"


def test_the_attachment_is_what_zenoh_ext_serializes() -> None:
    gid = gid_of("@ros2_lv/0/abc/0/1/MP/%/%/n/%t/std_msgs::msg::dds_::String_/h/::,10:,:,:,,")
    assert len(gid) == 16
    ours = encode_attachment(7, 1_700_000_000_123_456_789, gid)
    ext = zenoh.ext
    theirs = ext.z_serialize(
        (ext.Int64(7), ext.Int64(1_700_000_000_123_456_789), [ext.UInt8(b) for b in gid])
    )
    assert ours == theirs.to_bytes()
    assert decode_attachment(ours) == (7, 1_700_000_000_123_456_789, gid)
    for bad in (None, b"", ours[:-1], ours[:16] + b"\x0f" + ours[17:]):
        with pytest.raises(ValueError):
            decode_attachment(bad)


def test_attitudes_go_from_frd_ned_to_flu_enu_and_back() -> None:
    # Level, nose north: base_link's x points north, i.e. a yaw of +90 deg in ENU.
    q = flu_to_enu((1.0, 0.0, 0.0, 0.0))
    assert [abs(c) for c in q] == pytest.approx([0.5**0.5, 0.0, 0.0, 0.5**0.5])
    heading_east_pitched = (
        0.7010573846499779,
        0.0922959556412572,
        0.0922959556412572,
        0.7010573846499779,
    )
    back = frd_to_ned(flu_to_enu(heading_east_pitched))
    sign = 1.0 if back[0] * heading_east_pitched[0] > 0 else -1.0
    assert [sign * c for c in back] == pytest.approx(list(heading_east_pitched))


def test_an_estimate_in_another_frame_is_refused() -> None:
    msgs = Messages(typestore("jazzy"))
    t = msgs.store.types
    pose = t["geometry_msgs/msg/PoseWithCovarianceStamped"](
        header=msgs.header(1_500_000_000, "odom"),
        pose=t["geometry_msgs/msg/PoseWithCovariance"](
            pose=t["geometry_msgs/msg/Pose"](
                position=t["geometry_msgs/msg/Point"](x=1.0, y=2.0, z=3.0),
                orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
            covariance=__import__("numpy").zeros(36),
        ),
    )
    with pytest.raises(ValueError, match="frame_id 'odom'"):
        estimate_of(pose, "geometry_msgs/msg/PoseWithCovarianceStamped")
    pose.header.frame_id = "map"
    est = estimate_of(pose, "geometry_msgs/msg/PoseWithCovarianceStamped")
    assert est.sim_time_ns == 1_500_000_000 and est.enu_m == (1.0, 2.0, 3.0)
    assert est.cov_enu_m2 is None  # an all-zero covariance says nothing


@pytest.mark.parametrize(
    ("option", "value", "says"),
    [
        ("--ros-domain-id", "233", "--ros-domain-id 233: expected an integer 0..232"),
        ("--ros-domain-id", "x", "--ros-domain-id x: expected an integer 0..232"),
        ("--ros-namespace", "/a/9b", "'9b' is not a ROS 2 name"),
    ],
)
def test_bad_ros2_options_are_one_line(
    option: str, value: str, says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = str(write_short_plan(tmp_path / "p.plan", HOME))
    argv = ["fly", plan, "--out", str(tmp_path / "a"), "--ros2", option, value]
    assert says in one_line_error(argv, capsys)


def test_a_vehicle_name_ros2_cannot_take_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = str(write_short_plan(tmp_path / "p.plan", HOME))
    argv = ["fly", plan, "--out", str(tmp_path / "a"), "--ros2", "--vehicle", "uav-1"]
    assert "'uav-1' is not a ROS 2 name" in one_line_error(argv, capsys)


IMU, CLOCK = "sensor_msgs/msg/Imu", "rosgraph_msgs/msg/Clock"


def stamps(peer: RosPeer, key: str, kind: str) -> set[int]:
    """The stamps (ns) of the messages the peer received on ``key``."""
    out = set()
    for sample in peer.received(key):
        m = STORE.deserialize_cdr(sample.payload, kind)
        stamp = m.clock if kind == CLOCK else m.header.stamp
        out.add(stamp.sec * 1_000_000_000 + stamp.nanosec)
    return out


def test_namespace_and_domain_id_place_node_and_topics() -> None:
    endpoint = free_endpoint()
    peer = RosPeer(listen=(endpoint,), domain=7)
    bus = open_bus(BusConfig(listen=(), connect=(endpoint,), timestamping=True))
    try:
        node = open_node(bus, Ros2Options(domain_id=7, namespace="/sim/a"), KeySpace())
        view = Ros2View(node, KeySpace(), camera=None, publish_truth=False, imu_rate_hz=200.0)
        imu_key = data_key(7, "/sim/a/air/uav0/imu", "sensor_msgs/msg/Imu")
        clock_key = data_key(7, "/clock", "rosgraph_msgs/msg/Clock")
        assert wait_until(lambda: len([t for t in peer.tokens if t.kind == "MP"]) == 3)
        # The peer's subscriptions may reach this session after its tokens (a loaded machine):
        # samples put before are not routed. Put samples until one arrives, then ten more,
        # which must arrive on both topics by their stamps; the view's puts drop on
        # congestion (air_sitl.bus.session), so on a loaded machine some of the ten may be
        # lost: at least one on both, and none elsewhere.
        step = iter(range(0, 10**12, 5_000_000))

        def one_through() -> bool:
            view.on_sample(make_sample(next(step)))
            return bool(peer.received(imu_key)) and bool(peer.received(clock_key))

        assert wait_until(one_through)
        ten = [next(step) for _ in range(10)]
        for t_ns in ten:
            view.on_sample(make_sample(t_ns))
        assert wait_until(
            lambda: bool(set(ten) & stamps(peer, imu_key, IMU) & stamps(peer, clock_key, CLOCK))
        )
    finally:
        bus.close()
        peer.close()
    (n,) = [t for t in peer.tokens if t.kind == "NN"]
    assert (n.domain, n.namespace, n.node) == (7, "/sim/a", "air_sitl_uav0")
    assert n.key.split("/")[7] == "%sim%a"
    topics = {t.topic for t in peer.tokens if t.kind == "MP"}
    assert topics == {"/sim/a/air/uav0/imu", "/sim/a/air/uav0/gnss/fix", "/clock"}
    gnss_key = data_key(7, "/sim/a/air/uav0/gnss/fix", "sensor_msgs/msg/NavSatFix")
    assert {s.key for s in peer.samples} <= {imu_key, clock_key, gnss_key}
