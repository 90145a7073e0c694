"""``camera-bridge --foxglove 127.0.0.1:0``: frames the bridge renders from the bus's truth reach
a client written from the protocol's spec, byte for byte the frames it published on zenoh."""

from __future__ import annotations

import re

import pytest
from bus.helpers import (
    HOME,
    cli,
    free_endpoint,
    make_sample,
    start,
    stop,
    wait_for_line,
    wait_until,
)

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.session import BusConfig, Message, open_bus

from .ws_client import FoxgloveClient

pytestmark = pytest.mark.integration

V = "/air/uav0/"


def test_camera_bridge_shows_its_frames_in_foxglove() -> None:
    sim_ep = free_endpoint()
    sim = open_bus(BusConfig(listen=(sim_ep,), connect=(), serves=True))
    frames: list[Message] = []
    sim.subscribe(KeySpace().image, frames.append)
    bridge = start(
        cli("camera-bridge", "--map", "urban", "--zenoh-connect", sim_ep, "--foxglove",
            "127.0.0.1:0", "--foxglove-image-hz", "50")
    )  # fmt: skip
    client = None
    try:
        assert bridge.stderr is not None
        line = bridge.stderr.readline()
        port = int(re.search(r"foxglove: ws://127\.0\.0\.1:(\d+) \(uav0\)", line).group(1))  # type: ignore[union-attr]
        wait_for_line(bridge, "serving")
        pub = BusPublisher(sim, PublishOptions(publish_truth=True, home=HOME))
        assert wait_until(lambda: pub._truth is not None and pub._truth.matched)
        # 200 Hz physics, a camera exposure every 4th step (50 Hz): frames 0..9.
        samples = [
            make_sample(i * 5_000_000, east_m=0.075 * i, frame=None if i % 4 else i // 4)
            for i in range(40)
        ]
        pub.on_sample(samples[0])  # frame 0 makes the channels
        client = FoxgloveClient("127.0.0.1", port)
        while not {V + "camera/image", V + "camera/calibration"} <= client.topics():
            client.recv()
        client.subscribe([V + "camera/image", V + "camera/calibration"])
        while client.next_message()[0] != V + "camera/calibration":  # latched: subscribed
            pass
        for s in samples[1:]:
            pub.on_sample(s)
        images: dict[int, bytes] = {}
        while len(images) < 9:
            topic, t_ns, value = client.next_message()
            if topic == V + "camera/image":
                images[t_ns] = value.data
        assert wait_until(lambda: len(frames) == 10)
    finally:
        if client is not None:
            client.close()
        code, _, err = stop(bridge)
        sim.close()
    assert code == 0, err
    ours = {codec.decode_frame_meta(m.attachment).sim_time_ns: m.payload for m in frames}
    assert sorted(images) == sorted(ours)[1:]
    for t, jpeg in images.items():
        assert jpeg == ours[t]
