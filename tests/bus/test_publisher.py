"""The publisher sink on a real session: what goes out, how often, and GNSS denial."""

from __future__ import annotations

import json
import threading

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.session import Message
from air_sitl.clock import NS_PER_S, PHYSICS_STEP_NS
from air_sitl.sensors import SensorSuite
from air_sitl.state import CameraFrame

from .helpers import HOME, free_endpoint, make_sample, pair, wait_until

KEYS = KeySpace("t1")


class Collector:
    """Every message received, by key, from any thread."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.by_key: dict[str, list[Message]] = {}

    def __call__(self, m: Message) -> None:
        with self.lock:
            self.by_key.setdefault(m.key, []).append(m)

    def count(self, key: str) -> int:
        with self.lock:
            return len(self.by_key.get(key, []))

    def json(self, key: str) -> list[dict[str, object]]:
        with self.lock:
            return [json.loads(m.payload) for m in self.by_key.get(key, [])]


def test_topics_rates_truth_frame_index_and_latest_values() -> None:
    sim, client = pair(free_endpoint())
    with sim, client:
        got = Collector()
        client.subscribe(f"{KEYS.root}/**", got)
        pub = BusPublisher(
            sim, PublishOptions(keys=KEYS, publish_truth=True, imu_rate_hz=50.0, home=HOME)
        )
        assert wait_until(lambda: pub._clock.matched)
        steps = 400  # 2 s: capture from step 100 on, a frame every 4th step (50 Hz)
        for i in range(steps):
            t = i * PHYSICS_STEP_NS
            frame = (i - 100) // 4 if i >= 100 and i % 4 == 0 else None
            pub.on_sample(
                make_sample(t, capturing=i >= 100, gps=t % (NS_PER_S // 5) == 0, frame=frame)
            )
        assert wait_until(lambda: got.count(KEYS.clock) == steps)
        assert wait_until(lambda: got.count(KEYS.truth) == steps)
        assert got.count(KEYS.imu) == steps // 4  # 50 Hz of a 200 Hz simulation
        assert [m["sim_time_ns"] for m in got.json(KEYS.gps)] == [
            k * NS_PER_S // 5 for k in range(10)
        ]
        frames = [
            (m["frame"], m["sim_time_ns"]) for m in got.json(KEYS.truth) if m["frame"] is not None
        ]
        assert frames == [(k, (100 + 4 * k) * PHYSICS_STEP_NS) for k in range(75)]
        statuses = got.json(KEYS.mission_status)
        assert statuses[0]["home"] == {"lat_deg": HOME.lat_deg, "lon_deg": HOME.lon_deg,
                                       "alt_amsl_m": HOME.alt_amsl_m}  # fmt: skip
        assert any(s["capturing"] for s in statuses) and not statuses[0]["capturing"]
        # A late joiner asks for the latest value of each small topic.
        last_clock = json.loads(client.query(KEYS.clock).payload)
        assert last_clock["sim_time_ns"] == (steps - 1) * PHYSICS_STEP_NS
        assert json.loads(client.query(KEYS.gps).payload)["sim_time_ns"] == 9 * NS_PER_S // 5
        # No camera description given: camera/info describes the frames when they come.
        sample = make_sample(0)
        pub.on_frame(CameraFrame(index=0, sim_time_ns=0, jpeg=b"\xff\xd8x", width_px=64,
                                 height_px=48, sample=sample, map_xy_px=(1, 2)))  # fmt: skip
        assert wait_until(lambda: got.count(KEYS.image) == 1)
        image = got.by_key[KEYS.image][0]
        assert image.payload == b"\xff\xd8x"
        meta = codec.decode_frame_meta(image.attachment)
        assert (meta.frame, meta.sim_time_ns, meta.width_px) == (0, 0, 64)
        info = codec.decode_camera_info(client.query(KEYS.info).payload)
        assert (info.width_px, info.height_px, info.hfov_deg) == (64, 48, 57.0)
        pub.on_frame(CameraFrame(index=0, sim_time_ns=0, jpeg=b"x", width_px=64, height_px=48,
                                 sample=sample, map_xy_px=(1, 2)))  # fmt: skip
        assert pub.frames_published == 1  # a frame already out is not sent twice


def test_without_publish_truth_nothing_is_published_or_answered_on_truth() -> None:
    sim, client = pair(free_endpoint())
    with sim, client:
        got = Collector()
        client.subscribe(f"{KEYS.root}/**", got)
        pub = BusPublisher(sim, PublishOptions(keys=KEYS))
        assert wait_until(lambda: pub._clock.matched)
        for i in range(20):
            pub.on_sample(make_sample(i * PHYSICS_STEP_NS))
        assert wait_until(lambda: got.count(KEYS.imu) == 20)
        assert got.count(KEYS.truth) == 0


def test_gps_stops_inside_the_denial_window_and_resumes_after() -> None:
    window = (1 * NS_PER_S, 2 * NS_PER_S)
    sensors = SensorSuite(HOME, seed=3, step_ns=PHYSICS_STEP_NS, gps_denied_ns=(window,))
    sim, client = pair(free_endpoint())
    with sim, client:
        got = Collector()
        client.subscribe(KEYS.gps, got)
        pub = BusPublisher(sim, PublishOptions(keys=KEYS))
        assert wait_until(lambda: pub._gps.matched)
        for i in range(3 * 200):
            base = make_sample(i * PHYSICS_STEP_NS)
            imu, fix = sensors.sample(base.state)
            pub.on_sample(base.__class__(state=base.state, autopilot=base.autopilot, imu=imu,
                                         gps=fix))  # fmt: skip
        assert wait_until(lambda: got.count(KEYS.gps) == 10)
        times = [m["sim_time_ns"] for m in got.json(KEYS.gps)]
        assert times == [k * NS_PER_S // 5 for k in (*range(5), *range(10, 15))]
