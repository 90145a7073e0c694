"""The bus with real processes: fly in lockstep with the example localizer, a slow subscriber,
the standalone camera bridge, the router, GNSS denial and a vanished estimator.

Short plans (air start, about 300 frames) keep each flight to a few seconds; every process is
stopped with a signal and its exit code checked.
"""

from __future__ import annotations

import contextlib
import csv
import itertools
import json
import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.session import BusConfig, Message, open_bus
from air_sitl.state import CameraFrame

from .helpers import (
    HOME,
    REPO,
    WAIT_SAFETY,
    cli,
    free_endpoint,
    make_sample,
    start,
    stop,
    wait_for_line,
    wait_until,
)

pytestmark = pytest.mark.integration

LOCALIZER = str(REPO / "bridges" / "example_localizer.py")


def write_plan_file(path: Path, leg_m: float = 100.0) -> Path:
    """Air start at 200 m, a capture leg of ``leg_m`` east (about 330 frames per 100 m)."""
    return write_short_plan(path, HOME, leg_m=leg_m, name="UB")


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_plan_file(tmp_path_factory.mktemp("plan") / "UB-200.plan")


def fly(
    plan: Path, out: Path, *extra: str, timeout_s: float = 120.0
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        cli("fly", str(plan), "--out", str(out), "--air-start", "--quiet", *extra),
        capture_output=True, text=True, timeout=timeout_s, check=False,
    )  # fmt: skip


def read_csv(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def fly_with_example_localizer(plan: Path, out: Path) -> str:
    """A lockstep flight beside the example localizer; the localizer's output."""
    endpoint = free_endpoint()
    # The localizer listens, fly connects: either way round works (see the vanishing test).
    loc = start([sys.executable, LOCALIZER, "--name", "ex", "--zenoh-listen", endpoint])
    try:
        wait = ("--wait-for", "ex", *WAIT_SAFETY)
        run = fly(plan, out, "--zenoh-connect", endpoint, *wait, "--svo-columns", "ex")
        # The mission completed: the localizer exits by itself (a signal only if it does not).
        with contextlib.suppress(subprocess.TimeoutExpired):
            loc.wait(timeout=60)
    finally:
        code, stdout, stderr = stop(loc)
    assert run.returncode == 0, run.stderr
    assert code == 0, stderr
    assert "example_localizer: the flight ended;" in stdout, stdout
    return stdout


def without_wall_clock(path: Path) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k != "latency_wall_ms"} for r in read_csv(path)]


def test_lockstep_with_the_example_localizer_answers_every_frame(
    plan: Path, tmp_path: Path
) -> None:
    out = tmp_path / "a"
    stdout = fly_with_example_localizer(plan, out)
    meta = read_csv(out / "metadata.csv")
    n = len(meta)
    assert n > 250
    rows = read_csv(out / "estimates" / "ex.csv")
    assert [int(r["frame"]) for r in rows] == list(range(n))  # one row per frame, in order
    assert all(r["latency_frames"] == "0" for r in rows)  # lag 1: frame k+1 waits for k
    assert f"{n} frames, {n} estimates" in stdout, stdout
    summary = json.loads((out / "summary.json").read_text())
    assert summary["frames_published"] == n and summary["estimates"] == {"ex": n}, summary
    manifest = json.loads((out / "manifest.json").read_text())
    assert "estimates/ex.csv" in manifest["files"]
    # SvoX..Z hold the estimator's ENU positions; and it is a working (if drifting) VO.
    errors = []
    for r, m in zip(rows, meta, strict=True):
        if r["east_m"] == "nan":
            continue
        assert float(m["SvoX"]) == pytest.approx(float(r["east_m"]), abs=1e-3)
        assert float(m["SvoY"]) == pytest.approx(float(r["north_m"]), abs=1e-3)
        errors.append(math.hypot(float(r["east_m"]) - float(m["PoseX"]),
                                 float(r["north_m"]) - float(m["PoseY"])))  # fmt: skip
    assert len(errors) == n, [r for r in rows if r["east_m"] == "nan"][:3]
    assert max(errors) < 15.0, errors
    # In lockstep the example's estimates are the same every time: it reads the bus through
    # one subscription, so each frame finds the IMU attitude and GNSS fix of its own step.
    fly_with_example_localizer(plan, tmp_path / "b")
    again = without_wall_clock(tmp_path / "b" / "estimates" / "ex.csv")
    assert again == without_wall_clock(out / "estimates" / "ex.csv")


SLOW_SUBSCRIBER = """
import sys, threading
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.bus.signals import wait_until_signalled
got = []
stop = threading.Event()
def slow(message):
    if not stop.is_set():
        got.append(message.key)
        stop.wait(1.0)  # a consumer far slower than 50 Hz
with open_bus(BusConfig(listen=(sys.argv[1],), connect=())) as bus:
    bus.subscribe(KeySpace().image, slow)
    print("ready", flush=True)
    wait_until_signalled()
    print(f"received {len(got)}", flush=True)
    stop.set()
"""


def test_a_slow_subscriber_does_not_slow_the_simulation(plan: Path, tmp_path: Path) -> None:
    script = tmp_path / "slow.py"
    script.write_text(SLOW_SUBSCRIBER)
    walls: dict[str, list[float]] = {"alone": [], "slow": []}
    received = []
    for k in range(1):  # the ratio is printed, not tested: one pair is enough
        for case in ("alone", "slow"):
            endpoint = free_endpoint()
            sub = None
            if case == "slow":  # it listens: fly connects before it publishes anything
                sub = start([sys.executable, str(script), endpoint])
                wait_for_line(sub, "ready")
            t0 = time.monotonic()
            run = fly(plan, tmp_path / f"{case}{k}", "--zenoh-connect", endpoint, *SMALL_CAMERA)
            walls[case].append(time.monotonic() - t0)
            assert run.returncode == 0, run.stderr
            if sub is not None:
                code, out, err = stop(sub)
                assert code == 0, err
                received.append(int(out.split("received ")[1]))
    ratio = min(walls["slow"]) / min(walls["alone"])
    print(f"wall time with a 1 s/frame subscriber / without: {ratio:.2f}")  # a figure, not a test
    frames = len(read_csv(tmp_path / "alone0" / "metadata.csv"))
    # The proof that the simulation did not wait: every frame was published and recorded while
    # the 1 s/frame subscriber took only a few (waiting for it would deliver them all).
    assert len(read_csv(tmp_path / "slow0" / "metadata.csv")) == frames
    # It got some and lost the rest: at 1 s a frame, about one per wall second of its flight.
    assert all(1 <= r < frames for r in received), received
    assert all(r <= wall + 2.0 for r, wall in zip(received, walls["slow"], strict=True)), received


def test_remote_camera_frames_are_byte_identical_to_the_local_camera(
    plan: Path, tmp_path: Path
) -> None:
    endpoint = free_endpoint()
    # The standalone entry point (bridges/camera_bridge.py runs `air-sitl camera-bridge`).
    bridge = start([sys.executable, str(REPO / "bridges" / "camera_bridge.py"), "--map", "urban",
                    "--zenoh-connect", endpoint])  # fmt: skip
    try:
        wait_for_line(bridge, "serving")
        remote = fly(plan, tmp_path / "remote", "--camera", "remote", "--zenoh-listen", endpoint)
    finally:
        code, out, err = stop(bridge, signal.SIGTERM)
    assert remote.returncode == 0, remote.stderr
    assert code == 0, err
    local = fly(plan, tmp_path / "local")
    assert local.returncode == 0, local.stderr
    a, b = tmp_path / "local", tmp_path / "remote"
    names = sorted(p.name for p in a.iterdir() if p.suffix == ".jpg")
    assert len(names) > 250 and names == sorted(p.name for p in b.iterdir() if p.suffix == ".jpg")
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert (a / "metadata.csv").read_bytes() == (b / "metadata.csv").read_bytes()
    assert f"{len(names)} frames rendered" in out


def test_router_mode_delivers_frames_between_clients() -> None:
    endpoint = free_endpoint()
    router = start(cli("router", "--listen", endpoint))
    try:
        wait_for_line(router, "listening on")
        client = BusConfig(mode="client", listen=(), connect=(endpoint,))
        with open_bus(client) as sim, open_bus(client) as sub:
            got: list[Message] = []
            sub.subscribe(KeySpace().image, got.append)
            pub = BusPublisher(sim, PublishOptions())
            assert wait_until(lambda: pub.image_matched)
            sample = make_sample(0)
            for k in range(50):
                jpeg = bytes([k]) * 60_000
                pub.on_frame(CameraFrame(index=k, sim_time_ns=k * 20_000_000, jpeg=jpeg,
                                         width_px=640, height_px=480, sample=sample,
                                         map_xy_px=(0, 0)))  # fmt: skip
                assert wait_until(lambda k=k: len(got) == k + 1)  # delivered before the next
            assert len(got) == 50
            assert [codec.decode_frame_meta(m.attachment).frame for m in got] == list(range(50))
            assert all(m.payload == bytes([k]) * 60_000 for k, m in enumerate(got))
    finally:
        code, out, err = stop(router)
    assert code == 0, err
    assert "stopped" in out


GPS_LISTENER = """
import json, sys
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.bus.signals import wait_until_signalled
times = []
with open_bus(BusConfig(listen=(sys.argv[1],), connect=(), serves=True)) as bus:
    bus.subscribe(KeySpace().gps, lambda m: times.append(json.loads(m.payload)["sim_time_ns"]))
    print("ready", flush=True)
    wait_until_signalled()
print(json.dumps(times), flush=True)
"""


def test_gps_stops_in_the_denial_window_and_the_archive_records_it(
    plan: Path, tmp_path: Path
) -> None:
    script = tmp_path / "gps.py"
    script.write_text(GPS_LISTENER)
    endpoint = free_endpoint()
    listener = start([sys.executable, str(script), endpoint])
    try:
        wait_for_line(listener, "ready")
        denial = ("--gps-denied-window", "2:4")
        run = fly(plan, tmp_path / "a", "--zenoh-connect", endpoint, *denial, *SMALL_CAMERA)
    finally:
        code, out, err = stop(listener)
    assert run.returncode == 0, run.stderr
    assert code == 0, err
    times = json.loads(out.strip().splitlines()[-1])
    assert not [t for t in times if 2e9 <= t < 4e9]
    assert [t for t in times if t < 2e9] and [t for t in times if t >= 4e9]
    after = [t for t in times if t >= 4e9]
    assert after[0] == 4_000_000_000 and all(
        b - a == 200_000_000 for a, b in itertools.pairwise(after)
    )
    manifest = json.loads((tmp_path / "a" / "manifest.json").read_text())
    assert manifest["gps_denied"] == [
        {"start_ns": 2_000_000_000, "end_ns": 4_000_000_000, "start_s": 2.0, "end_s": 4.0}
    ]


def test_an_estimator_that_vanishes_stops_the_run_with_one_line(plan: Path, tmp_path: Path) -> None:
    endpoint = free_endpoint()
    loc = start([sys.executable, LOCALIZER, "--name", "ex", "--zenoh-connect", endpoint])
    out = tmp_path / "a"
    flyer = start(cli("fly", str(plan), "--out", str(out), "--air-start", "--quiet",
                      "--zenoh-listen", endpoint, "--wait-for", "ex", "--wait-timeout", "8",
                      "--speed", "1"))  # fmt: skip
    try:
        assert wait_until(
            lambda: (
                (out / "estimates" / "ex.csv").exists()
                and len((out / "estimates" / "ex.csv").read_text().splitlines()) > 20
            ),
        )
    finally:
        loc.kill()
        loc.wait()
    _out, stderr = flyer.communicate(timeout=90)
    code = flyer.returncode
    assert code == 2, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in stderr
    assert "--wait-for ex: no estimate for frame" in lines[0] and "within 8 s" in lines[0]
    assert len(read_csv(out / "estimates" / "ex.csv")) >= 20  # what came is kept
    assert (out / "trajectory.csv").stat().st_size > 0


def test_serve_publishes_on_the_bus_and_stops_cleanly(plan: Path) -> None:
    endpoint = free_endpoint()
    keys = KeySpace("srv")
    with open_bus(BusConfig(listen=(endpoint,), connect=(), serves=True)) as bus:
        got: dict[str, list[bytes]] = {}
        bus.subscribe(f"{keys.root}/**", lambda m: got.setdefault(m.key, []).append(m.payload))
        serve = start(cli("serve", "--plan", str(plan), "--zenoh-connect", endpoint,
                          "--vehicle", "srv", "--mavlink", "udpin:127.0.0.1:0",
                          "--speed", "4", "--quiet", "--no-video"))  # fmt: skip
        try:
            assert wait_until(lambda: len(got.get(keys.imu, [])) > 50)
            assert wait_until(lambda: keys.mission_status in got)
        finally:
            code, _out, err = stop(serve)
        assert code == 0, err
        status = json.loads(got[keys.mission_status][0])
        assert status["home"]["lat_deg"] == pytest.approx(HOME.lat_deg)
        assert status["armed"] is False and keys.truth not in got
        info = codec.decode_camera_info(got[keys.info][0])  # serve renders for the bus too
        assert (info.width_px, info.height_px, info.hfov_deg) == (640, 480, 57.0)


# docs/bus.md's client example, verbatim but for the endpoint (raw zenoh, nothing of air-sitl).
README_CLIENT = """
import json
import zenoh

conf = zenoh.Config()
conf.insert_json5("connect/endpoints", '["tcp/127.0.0.1:7447"]')
conf.insert_json5("listen/endpoints", "[]")
conf.insert_json5("scouting/multicast/enabled", "false")
with zenoh.open(conf) as session:
    estimates = session.declare_publisher("air/uav0/estimate/mine")

    def on_frame(sample: zenoh.Sample) -> None:
        meta = json.loads(sample.attachment.to_bytes())  # frame, sim_time_ns, width_px ...
        jpeg = sample.payload.to_bytes()  # cv2.imdecode(numpy.frombuffer(jpeg, numpy.uint8), 1)
        east, north, up = 0.0, 0.0, 200.0  # your localization here
        estimates.put(json.dumps({"frame": meta["frame"], "enu_m": [east, north, up]}))

    session.declare_subscriber("air/uav0/camera/image", on_frame)
    input("estimating; Enter stops\\n")
"""


def test_the_readme_client_example_works_in_lockstep(plan: Path, tmp_path: Path) -> None:
    endpoint = free_endpoint()
    script = tmp_path / "client.py"
    script.write_text(README_CLIENT.replace("tcp/127.0.0.1:7447", endpoint))
    client = subprocess.Popen(
        [sys.executable, str(script)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        run = fly(
            plan, tmp_path / "a", "--zenoh-listen", endpoint, "--wait-for", "mine", *WAIT_SAFETY
        )
    finally:
        _out, err = client.communicate("\n", timeout=20)
    assert run.returncode == 0, run.stderr
    assert client.returncode == 0, err
    n = len(read_csv(tmp_path / "a" / "metadata.csv"))
    rows = read_csv(tmp_path / "a" / "estimates" / "mine.csv")
    assert [int(r["frame"]) for r in rows] == list(range(n))
    assert {(r["east_m"], r["up_m"]) for r in rows} == {("0.0000", "200.0000")}
