"""The online driver's bookkeeping on a fake bus: IMU slices, GNSS gating, one answer per frame."""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable
from typing import Any

import pytest

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import Message
from air_sitl.errors import BusError
from air_sitl.frames import euler2quat
from air_sitl.localize.base import Estimate, LocalizerContext, Observation
from air_sitl.localize.online import BusLocalizer
from air_sitl.state import GeoPoint, ImuSample

KEYS = KeySpace("t")
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
STEP_NS = 5_000_000
FRAME_NS = 20_000_000


class FakePublisher:
    def __init__(self) -> None:
        self.sent: list[dict[str, Any]] = []

    def put(self, payload: bytes, attachment: bytes | None = None) -> None:
        self.sent.append(json.loads(payload))


class FakeBus:
    """Answers the queries a localizer makes at start; records its subscriptions."""

    def __init__(self) -> None:
        self.subs: dict[str, Callable[[Message], None]] = {}
        self.out = FakePublisher()
        self.callback_errors: list[str] = []
        info = codec.CameraInfo(
            width_px=640,
            height_px=480,
            hfov_deg=57.0,
            rate_hz=50.0,
            q_cam_to_body_wxyz=(0.7071067811865476, 0.0, 0.0, 0.7071067811865476),
        )
        status = {
            "sim_time_ns": 0,
            "capturing": True,
            "mission_completed": False,
            "home": {"lat_deg": HOME.lat_deg, "lon_deg": HOME.lon_deg, "alt_amsl_m": 120.0},
        }
        self.answers = {
            KEYS.info: codec.encode_camera_info(info),
            KEYS.mission_status: codec.dumps(status),
        }

    def subscribe(self, key: str, callback: Callable[[Message], None]) -> None:
        self.subs[key] = callback

    def query(self, key: str, payload: bytes = b"", **_kw: Any) -> Message:
        if key not in self.answers:
            raise BusError(f"{key}: no answer")
        return Message(key, self.answers[key], None)

    def publisher(self, key: str, **_kw: Any) -> FakePublisher:
        return self.out

    def send(self, key: str, payload: bytes, attachment: bytes | None = None) -> None:
        """Deliver to the subscription of ``key``, or of the key space (``air/v/**``)."""
        sub = self.subs.get(key) or self.subs[f"{KEYS.root}/**"]
        sub(Message(key, payload, attachment))


class Recorder:
    """A method that keeps what it was given and answers every other frame."""

    name = "rec"
    needs_image = False

    def __init__(self) -> None:
        self.seen: list[Observation] = []
        self.resets = 0

    def reset(self, context: LocalizerContext) -> None:
        self.resets += 1
        assert context.home.lat_deg == HOME.lat_deg

    def step(self, obs: Observation) -> Estimate | None:
        self.seen.append(obs)
        if obs.frame % 2:
            return None
        return Estimate(frame=obs.frame, sim_time_ns=obs.sim_time_ns, enu_m=(1.0, 2.0, 3.0))


def fly(bus: FakeBus, frames: int, *, first_frame_ns: int = 100 * STEP_NS) -> None:
    """IMU at 200 Hz, GNSS at 5 Hz, frames at 50 Hz from ``first_frame_ns``, in step order."""
    frame = 0
    for step in range(first_frame_ns // STEP_NS + frames * 4):
        t = step * STEP_NS
        imu = ImuSample(
            sim_time_ns=t,
            gyro_frd_rad_s=(0.0, 0.0, 0.0),
            accel_frd_m_s2=(0.0, 0.0, -9.8),
            q_ahrs_body_to_ned_wxyz=euler2quat(0.0, 0.0, step * 1e-3),
        )
        bus.send(KEYS.imu, codec.encode_imu(imu))
        if t % 200_000_000 == 0:
            fix = {"sim_time_ns": t, "lat_deg": 54.7, "lon_deg": 25.3, "alt_amsl_m": 320.0,
                   "vel_ned_m_s": [15.0, 0.0, 0.0], "fix_type": 3}  # fmt: skip
            bus.send(KEYS.gps, codec.dumps(fix))
        if t >= first_frame_ns and (t - first_frame_ns) % FRAME_NS == 0 and frame < frames:
            meta = codec.FrameMeta(frame=frame, sim_time_ns=t, width_px=640, height_px=480)
            bus.send(KEYS.image, b"jpeg", codec.encode_frame_meta(meta))
            frame += 1


def drain(loc: BusLocalizer) -> None:
    while not loc._frames.empty():
        f = loc._frames.get_nowait()
        loc.handle(f.meta, f.jpeg)


@pytest.mark.parametrize("gnss", ["first", "all"])
def test_observations_from_the_bus(gnss: str) -> None:
    bus = FakeBus()
    method = Recorder()
    loc = BusLocalizer(bus, KEYS, method, "rec", wait_s=1.0, gnss=gnss)  # type: ignore[arg-type]
    fly(bus, 30)
    drain(loc)
    seen = method.seen
    assert [o.frame for o in seen] == list(range(30))
    first = seen[0]
    assert first.gnss is not None and first.gnss.sim_time_ns == 400_000_000
    assert len(first.imu) == 1 and first.imu[0].sim_time_ns == first.sim_time_ns
    for a, b in itertools.pairwise(seen):
        steps = [a.sim_time_ns + k * STEP_NS for k in (1, 2, 3, 4)]
        assert [s.sim_time_ns for s in b.imu] == steps
        assert b.q_ahrs_body_to_ned_wxyz == b.imu[-1].q_ahrs_body_to_ned_wxyz
        assert b.airspeed_m_s is None and b.baro_alt_rel_m is None and b.jpeg == b"jpeg"
    later = [o.gnss.sim_time_ns for o in seen[1:] if o.gnss is not None]
    # fixes every 200 ms = every 10 frames: given once each with --gnss all, never with first
    assert later == ([] if gnss == "first" else [600_000_000, 800_000_000, 1_000_000_000])
    sent = bus.out.sent
    assert [m["frame"] for m in sent] == list(range(30))  # every frame gets an answer
    assert sent[0]["enu_m"] == [1.0, 2.0, 3.0] and "enu_m" not in sent[1]
    assert loc.estimated == 15


def test_a_repeat_is_ignored_and_frame_zero_again_restarts() -> None:
    bus = FakeBus()
    method = Recorder()
    loc = BusLocalizer(bus, KEYS, method, "rec", wait_s=1.0)  # type: ignore[arg-type]
    fly(bus, 5)
    drain(loc)
    meta = codec.FrameMeta(frame=3, sim_time_ns=0, width_px=640, height_px=480)
    assert loc.handle(meta, b"jpeg") is None  # a repeat of an older frame: nothing sent
    assert len(bus.out.sent) == 5
    fly(bus, 2)  # a new capture window, frame 0 again
    drain(loc)
    assert method.resets == 2
    assert [m["frame"] for m in bus.out.sent] == [0, 1, 2, 3, 4, 0, 1]
    # The closing line counts the new window's frames and estimates, not the old ones too.
    assert loc.frames == 2 and loc.estimated == sum("enu_m" in m for m in bus.out.sent[5:])
    # Frame 0 twice in a row is a repeat, not a third window.
    other = FakeBus()
    fresh = BusLocalizer(other, KEYS, Recorder(), "rec", wait_s=1.0)  # type: ignore[arg-type]
    fly(other, 1)
    drain(fresh)
    meta0 = codec.FrameMeta(frame=0, sim_time_ns=0, width_px=640, height_px=480)
    assert fresh.handle(meta0, b"jpeg") is None
    # Offered again (lockstep after a lost connection): the same answer again, not a new one.
    assert fresh.frames == 1 and [m["frame"] for m in other.out.sent] == [0, 0]
    assert other.out.sent[0] == other.out.sent[1]
