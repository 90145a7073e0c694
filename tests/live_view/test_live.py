"""The live view's server (``--foxglove``) read by a client written from the protocol's spec.

The sink is fed the scripted flight of the dataset tests (real states, real JPEGs) at the
test's own pace, so nothing depends on wall-clock speed; the server and the client are real
(a socket on port 0).
"""

from __future__ import annotations

import io
import json
import math
import re
from pathlib import Path

import pytest

from air_sitl.bus.codec import Estimate
from air_sitl.camera.model import CameraModel
from air_sitl.foxglove.live import FoxgloveLive, LiveOptions
from air_sitl.frames import ned2enu
from air_sitl.mission.plan_file import read_plan
from air_sitl.state import CameraFrame
from tests.dataset.synth import CAPTURE_START_NS, HOME, H, W, jpeg_of, samples

from .ws_client import SUBPROTOCOL, FoxgloveClient

FRAMES = 30
MISSIONS = Path(__file__).resolve().parents[2] / "missions"
V = "/air/uav0/"
FIRST = CAPTURE_START_NS  # the first phase ends with the first frame


def _collect(client: FoxgloveClient, until: str) -> dict[str, list[tuple[int, object]]]:
    """Every message until the log line ``until``; subscribes to each channel advertised."""
    got: dict[str, list[tuple[int, object]]] = {}
    while True:
        topic, t_ns, value = client.next_message()
        got.setdefault(topic, []).append((t_ns, value))
        if topic == V + "log" and value.message == until:
            return got


def _estimate(live: FoxgloveLive, frame: CameraFrame) -> None:
    """An estimator's answer 3 m east of the truth (what the bus's EstimateLog hands on)."""
    e, n, u = ned2enu(frame.sample.state.pos_ned_m)
    t = frame.sim_time_ns
    est = Estimate(frame=frame.index, sim_time_ns=t, enu_m=(e + 3.0, n, u), geo=None)
    live.on_estimate("vpr", frame.index, t, est)


@pytest.fixture
def live() -> FoxgloveLive:
    view = FoxgloveLive(
        LiveOptions(host="127.0.0.1", port=0, image_hz=10.0),
        vehicle="uav0",
        home=HOME,
        camera=CameraModel(width_px=W, height_px=H),
        out=io.StringIO(),
    )
    yield view  # type: ignore[misc]
    view.close()


def test_a_client_sees_the_flight_and_a_late_one_gets_calibration_and_mission(
    live: FoxgloveLive,
) -> None:
    printed = live.out.getvalue()  # type: ignore[attr-defined]
    assert re.search(rf"ws://127\.0\.0\.1:{live.port} ", printed), printed
    assert live.port
    mission = read_plan(MISSIONS / "FL-200.plan")
    live.start(mission)
    flight = list(samples(FRAMES))
    first = [(s, f) for s, f in flight if s.state.sim_time_ns <= FIRST]
    rest = [(s, f) for s, f in flight if s.state.sim_time_ns > FIRST]
    for sample, frame in first:
        live.on_sample(sample)
        if frame is not None:
            live.on_frame(frame)
            _estimate(live, frame)
    live.statustext(FIRST, "phase 1", 6)

    client = FoxgloveClient("127.0.0.1", live.port)
    assert client.protocol == SUBPROTOCOL
    kind, info = client.recv()
    assert kind == "json"
    assert info["op"] == "serverInfo", info
    # Everything phase 1 made is advertised; subscribe to all, then wait for the latched ones.
    phase1 = {V + "log", V + "camera/image", "/tf", V + "estimates/vpr/fix", V + "errors"}
    while not phase1 <= client.topics():
        client.recv()
    client.subscribe(sorted(client.topics()))
    latched: set[str] = set()
    while not {V + "camera/calibration", V + "mission", "/tf"} <= latched:
        item = client.recv()
        if item[0] == "message":
            latched.add(item[1])

    truth_by_t = {}
    for sample, frame in rest:
        live.on_sample(sample)
        if frame is not None:
            live.on_frame(frame)
            t = frame.sim_time_ns
            truth_by_t[t] = frame
            _estimate(live, frame)
    live.statustext(rest[-1][0].state.sim_time_ns, "the end", 6)
    got = _collect(client, "the end")

    images = got[V + "camera/image"]
    assert 5 <= len(images) <= FRAMES // 5 + 1  # 10 Hz of a 50 Hz camera
    for t, img in images:
        frame = truth_by_t[t]
        assert img.data == jpeg_of(frame.index) == frame.jpeg  # type: ignore[attr-defined]
        assert img.timestamp.seconds * 10**9 + img.timestamp.nanos == t  # type: ignore[attr-defined]
    states = {s.state.sim_time_ns: s.state for s, _ in flight}
    fixes = got[V + "truth/fix"]
    assert fixes
    for t, fix in fixes:
        st = states[t]
        assert (fix.latitude, fix.longitude, fix.altitude) == (  # type: ignore[attr-defined]
            st.lat_deg,
            st.lon_deg,
            st.alt_amsl_m,
        )
    for _, tf in got["/tf"]:
        for x in tf.transforms:  # type: ignore[attr-defined]
            assert (x.parent_frame_id, x.child_frame_id) in (
                ("map", "base_link"),
                ("base_link", "camera_optical_frame"),
            )
            r = x.rotation
            assert math.isclose(math.hypot(r.x, r.y, r.z, r.w), 1.0, abs_tol=1e-9)
    gnss = got[V + "gnss/fix"]
    assert gnss and all(g.position_covariance[0] == 1.5**2 for _, g in gnss)  # type: ignore[attr-defined]
    est_fixes = got[V + "estimates/vpr/fix"]
    assert len(est_fixes) == FRAMES - 1  # every frame after the first
    assert (
        client.channels_by_topic(V + "estimates/vpr/pose")["schemaName"] == "foxglove.PoseInFrame"
    )
    errs = [e for _, e in got[V + "errors"] if e["source"] == "estimates/vpr"]  # type: ignore[index]
    assert errs and all(abs(e["horizontal_m"] - 3.0) < 1e-6 for e in errs)  # type: ignore[index]
    client.close()

    late = FoxgloveClient("127.0.0.1", live.port)
    late.recv()
    while not {V + "camera/calibration", V + "mission"} <= late.topics():
        late.recv()
    late.subscribe([V + "camera/calibration", V + "mission"])
    seen: dict[str, object] = {}
    while len(seen) < 2:
        item = late.recv()
        if item[0] == "message":
            seen[item[1]] = item[3]
    cal = seen[V + "camera/calibration"]
    assert (cal.width, cal.height) == (W, H)  # type: ignore[attr-defined]
    doc = json.loads(seen[V + "mission"].geojson)  # type: ignore[attr-defined]
    assert any(f["properties"]["name"] == "route" for f in doc["features"])
    late.close()


def test_a_view_behind_the_flight_drops_counts_and_says_so() -> None:
    """The simulation side never waits: with room for 4 updates, a burst of 12000 frames
    overruns the worker; what it dropped is counted and printed when the view closes."""
    out = io.StringIO()
    view = FoxgloveLive(
        LiveOptions(host="127.0.0.1", port=None, image_hz=50.0),
        vehicle="uav0",
        home=HOME,
        camera=CameraModel(width_px=W, height_px=H),
        out=out,
        queue_depth=4,
    )
    frames = [f for _, f in samples(FRAMES) if f is not None]
    for _ in range(400):
        for frame in frames:
            view.on_frame(frame)
    view.close()
    assert view.dropped > 0 and view.handled > 0
    assert f"foxglove: {view.dropped} updates dropped" in out.getvalue()
    assert view.port is None and "ws://" not in out.getvalue()
