"""Zenoh bus speed: frame latency at 50 Hz, the loss-free frame rate, and a real flight.

Run: ``python benchmarks/bench_bus.py [--frames N]``. A subscriber runs as a separate process
(an external localizer's position); both sides stamp CLOCK_MONOTONIC, shared by processes.
Prints:

1. publish-to-receive latency of real 640x480 JPEG frames at 50 Hz: median and p99 (target
   p99 < 5 ms), beside the same for 100-byte messages on the same path (the floor) and the ratio;
2. the highest frame rate delivered without loss to one subscriber (paced sweep, drop mode);
3. ``air-sitl fly --zenoh --speed 0`` with that subscriber: frames/s published, frames lost.

With ``--ros2``: 1. for the ROS 2 view (``fly --ros2``) instead: CompressedImage samples laid
out as rmw_zenoh does (CDR, attachment) to a subscriber process on the rmw_zenoh key that
decodes each with rosbags, beside our own JPEG path and the 100-byte floor (target p99 < 5 ms).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.ros2.options import Ros2Options
from air_sitl.bus.ros2.view import Ros2View, open_node
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import ned2geodetic
from air_sitl.maps.open import open_map
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import write_plan
from air_sitl.state import AutopilotStatus, CameraFrame, FlightMode, GeoPoint, SimSample

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
KEYS = KeySpace("bench")

SUBSCRIBER = """
import json, sys, time
from air_sitl.bus.codec import decode_frame_meta
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.bus.signals import wait_until_signalled
keys = KeySpace(sys.argv[2])
got = {}
def on_frame(m):
    got[decode_frame_meta(m.attachment).frame] = time.monotonic_ns()
listen = sys.argv[3:] == ["listen"]
cfg = BusConfig(listen=(sys.argv[1],) if listen else (), connect=() if listen else (sys.argv[1],))
with open_bus(cfg) as bus:
    bus.subscribe(keys.image, on_frame)
    print("ready", flush=True)
    wait_until_signalled()
print(json.dumps(got), flush=True)
"""

ROS2_SUBSCRIBER = """
import json, sys, time
from rosbags.typesys import Stores, get_typestore
from air_sitl.bus.session import BusConfig, open_bus
from air_sitl.bus.signals import wait_until_signalled
store = get_typestore(Stores.ROS2_KILTED)
T = "sensor_msgs/msg/CompressedImage"
key = (f"0/air/{sys.argv[2]}/camera/image/compressed/sensor_msgs::msg::dds_::CompressedImage_/"
       f"{store.hash_rihs01(T)}")
got = {}
# rosbags compiles a type's deserializer on first use: do it before the frames come.
empty = store.types[T](header=store.types["std_msgs/msg/Header"](
    stamp=store.types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""),
    format="jpeg", data=__import__("numpy").zeros(0, dtype="uint8"))
store.deserialize_cdr(store.serialize_cdr(empty, T), T)
def on_frame(m):
    t = time.monotonic_ns()
    stamp = store.deserialize_cdr(m.payload, T).header.stamp
    got[(stamp.sec * 1_000_000_000 + stamp.nanosec) // 20_000_000] = t
with open_bus(BusConfig(listen=(), connect=(sys.argv[1],))) as bus:
    bus.subscribe(key, on_frame)
    print("ready", flush=True)
    wait_until_signalled()
print(json.dumps(got), flush=True)
"""


def frames(n: int) -> list[bytes]:
    """Real JPEG frames of a flight over ``urban`` at 200 m (about 80 kB each)."""
    renderer = Renderer(open_map("urban", HOME), CameraModel(), seed=0)
    out = []
    for k in range(n):
        lat, lon, alt = ned2geodetic(0.0, 0.3 * k, -200.0, HOME.lat_deg, HOME.lon_deg, 120.0)
        state = pose_state(lat, lon, alt, alt_agl_m=200.0, yaw_rad=1.57)
        out.append(renderer.frame_jpeg(state, k)[0])
    return out


class Subscriber:
    """The external subscriber process."""

    def __init__(self, endpoint: str, vehicle: str, script: Path, *, listen: bool = False) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, str(script), endpoint, vehicle, *(["listen"] if listen else [])],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert self.proc.stdout is not None
        assert self.proc.stdout.readline().strip() == "ready"

    def finish(self) -> dict[int, int]:
        time.sleep(0.5)
        self.proc.send_signal(2)
        out, _ = self.proc.communicate(timeout=30)
        return {int(k): v for k, v in json.loads(out.strip().splitlines()[-1]).items()}


def publish(
    endpoint: str, script: Path, payloads: list[bytes], rate_hz: float | None
) -> tuple[dict[int, int], dict[int, int]]:
    """Publish frames (paced at ``rate_hz``, or flat out) to a subscriber process."""
    sample = dummy_sample()
    with open_bus(BusConfig(listen=(endpoint,), connect=(), serves=True)) as bus:
        sub = Subscriber(endpoint, KEYS.vehicle, script)
        pub = BusPublisher(bus, PublishOptions(keys=KEYS))
        while not pub.image_matched:
            time.sleep(0.01)
        time.sleep(0.2)
        sent: dict[int, int] = {}
        start = time.monotonic()
        for k, jpeg in enumerate(payloads):
            if rate_hz is not None:
                delay = start + k / rate_hz - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            frame = CameraFrame(
                index=k,
                sim_time_ns=k * 20_000_000,
                jpeg=jpeg,
                width_px=640,
                height_px=480,
                sample=sample,
                map_xy_px=(0, 0),
            )
            sent[k] = time.monotonic_ns()
            pub.publish_frame(frame)
        got = sub.finish()
    return sent, got


def publish_ros2(
    endpoint: str, script: Path, payloads: list[bytes], rate_hz: float
) -> tuple[dict[int, int], dict[int, int]]:
    """Publish frames through the ROS 2 view (``--ros2``) to a ROS 2 subscriber process."""
    sample = dummy_sample()
    config = BusConfig(listen=(endpoint,), connect=(), serves=True, timestamping=True)
    with open_bus(config) as bus:
        sub = Subscriber(endpoint, KEYS.vehicle, script)
        node = open_node(bus, Ros2Options(), KEYS)
        view = Ros2View(node, KEYS, camera=CameraModel(), publish_truth=False, imu_rate_hz=200.0)
        while not view.image_matched:
            time.sleep(0.01)
        time.sleep(0.2)
        sent: dict[int, int] = {}
        start = time.monotonic()
        for k, jpeg in enumerate(payloads):
            delay = start + k / rate_hz - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            frame = CameraFrame(index=k, sim_time_ns=k * 20_000_000, jpeg=jpeg, width_px=640,
                                height_px=480, sample=sample, map_xy_px=(0, 0))  # fmt: skip
            sent[k] = time.monotonic_ns()
            view.publish_frame(frame)
        got = sub.finish()
    return sent, got


def ros2_latency(
    tmp: Path, script: Path, payloads: list[bytes], size_kb: float, rounds: int
) -> None:
    """Section 1 for the ROS 2 view, beside our own JPEG path and the 100-byte floor: the
    three alternate ``rounds`` times and each keeps its best round (lowest p99): on a shared,
    loaded machine a round's p99 is mostly the scheduler's."""
    ros2_script = tmp / "ros2_subscriber.py"
    ros2_script.write_text(ROS2_SUBSCRIBER)
    n = len(payloads)
    print(f"1. latency at 50 Hz, {n} frames, separate subscriber process, --ros2, "
          f"best of {rounds} alternating rounds")  # fmt: skip
    best: dict[str, tuple[float, float, int]] = {}
    runs = {
        "ros2": lambda: publish_ros2(free_endpoint(), ros2_script, payloads, 50.0),
        "ours": lambda: publish(free_endpoint(), script, payloads, 50.0),
        "floor": lambda: publish(free_endpoint(), script, [b"x" * 100] * n, 50.0),
    }
    for _ in range(rounds):
        for name, run in runs.items():
            result = latency_ms(*run())
            if name not in best or result[1] < best[name][1]:
                best[name] = result
    rmed, rp99, rlost = best["ros2"]
    med, p99, _ = best["ours"]
    fmed, fp99, _ = best["floor"]
    print(f"  ROS 2 CompressedImage {size_kb:.0f} kB: median {rmed:.2f} ms, p99 {rp99:.2f} ms, "
          f"lost {rlost}  (target p99 < 5 ms: {'met' if rp99 < 5 else 'MISSED'})")  # fmt: skip
    print(f"  our JPEG key, same frames: median {med:.2f} ms, p99 {p99:.2f} ms")
    print(f"  floor, 100 B:  median {fmed:.2f} ms, p99 {fp99:.2f} ms; ROS 2 ratio "
          f"{rmed / fmed:.1f}x median, {rp99 / fp99:.1f}x p99")  # fmt: skip


def dummy_sample() -> SimSample:
    from air_sitl.state import ImuSample

    state = pose_state(HOME.lat_deg, HOME.lon_deg, 320.0, alt_agl_m=200.0)
    status = AutopilotStatus(
        mode=FlightMode.MISSION, armed=True, current_seq=0, capturing=True, mission_completed=False
    )
    imu = ImuSample(
        sim_time_ns=0,
        gyro_frd_rad_s=(0.0, 0.0, 0.0),
        accel_frd_m_s2=(0.0, 0.0, -9.8),
        q_ahrs_body_to_ned_wxyz=state.q_body_to_ned_wxyz,
    )
    return SimSample(state=state, autopilot=status, imu=imu, gps=None)


def free_endpoint() -> str:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def latency_ms(sent: dict[int, int], got: dict[int, int]) -> tuple[float, float, int]:
    lat = sorted((got[k] - sent[k]) / 1e6 for k in got if k in sent)
    p99 = lat[min(len(lat) - 1, round(0.99 * (len(lat) - 1)))]
    return statistics.median(lat), p99, len(sent) - len(got)


def real_flight(script: Path, tmp: Path) -> None:
    """fly --zenoh --speed 0 over a 400 m capture leg with the subscriber attached."""

    def wp(n: float, e: float) -> MissionItem:
        lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        return MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=lat, lon_deg=lon, alt_m=200.0)

    items = (
        MissionItem(command=MavCmd.NAV_TAKEOFF, param1=15.0, lat_deg=HOME.lat_deg,
                    lon_deg=HOME.lon_deg, alt_m=200.0),
        wp(300.0, 0.0),
        MissionItem(command=MavCmd.IMAGE_START_CAPTURE, frame=MavFrame.MISSION, param2=0.02),
        wp(300.0, 400.0),
        MissionItem(command=MavCmd.IMAGE_STOP_CAPTURE, frame=MavFrame.MISSION),
        wp(300.0, 460.0),
    )  # fmt: skip
    plan = tmp / "UB.plan"
    write_plan(Mission(items=items, planned_home=HOME, cruise_speed_m_s=15.0, name="UB"), plan)
    for label, extra in (("without bus", []), ("--zenoh + subscriber", ["--zenoh"])):
        endpoint = free_endpoint()
        # The subscriber listens and fly connects at start-up: no frame goes out before it.
        sub = Subscriber(endpoint, "uav0", script, listen=True) if extra else None
        t0 = time.monotonic()
        run = subprocess.run(
            [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(tmp / label),
             "--air-start", "--quiet", "--zenoh-connect", endpoint, *extra],
            capture_output=True, text=True, check=False,
        )  # fmt: skip
        wall = time.monotonic() - t0
        assert run.returncode == 0, run.stderr
        summary = json.loads((tmp / label / "summary.json").read_text())
        n = summary["frames_written"]
        line = f"  {label:22s} {n} frames in {wall:5.1f} s wall = {n / wall:6.1f} frames/s"
        if sub is not None:
            got = sub.finish()
            first = min(got) if got else None
            line += f", subscriber received {len(got)} (lost {n - len(got)}; first: #{first})"
        print(line)


def main() -> None:
    parser = argparse.ArgumentParser(description="zenoh bus benchmark")
    parser.add_argument("--frames", type=int, default=500, help="frames per measurement")
    parser.add_argument(
        "--ros2", action="store_true", help="measure the ROS 2 view's frames (section 1 only)"
    )
    parser.add_argument(
        "--rounds", type=int, default=3, help="--ros2: alternating rounds, best kept (default 3)"
    )
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp_text:
        tmp = Path(tmp_text)
        script = tmp / "subscriber.py"
        script.write_text(SUBSCRIBER)
        jpegs = frames(50)
        payloads = [jpegs[k % len(jpegs)] for k in range(args.frames)]
        size_kb = statistics.mean(len(j) for j in jpegs) / 1000
        if args.ros2:
            ros2_latency(tmp, script, payloads, size_kb, max(1, args.rounds))
            return
        print(f"1. latency at 50 Hz, {args.frames} frames, separate subscriber process")
        med, p99, lost = latency_ms(*publish(free_endpoint(), script, payloads, 50.0))
        small = [b"x" * 100] * args.frames
        fmed, fp99, _ = latency_ms(*publish(free_endpoint(), script, small, 50.0))
        print(f"  JPEG {size_kb:.0f} kB: median {med:.2f} ms, p99 {p99:.2f} ms, lost {lost}"
              f"  (target p99 < 5 ms: {'met' if p99 < 5 else 'MISSED'})")  # fmt: skip
        print(f"  floor, 100 B:  median {fmed:.2f} ms, p99 {fp99:.2f} ms; "
              f"ratio {med / fmed:.1f}x median, {p99 / fp99:.1f}x p99")  # fmt: skip
        print("2. highest loss-free frame rate to one subscriber (paced, drop on congestion)")
        best = 0.0
        many = [jpegs[k % len(jpegs)] for k in range(4 * args.frames)]
        for rate in (500.0, 1000.0, 2000.0, 4000.0, 8000.0, None):
            sent, got = publish(free_endpoint(), script, many, rate)
            # Delivered rate: from the first publish to the last arrival, at the subscriber.
            span = (max(got.values()) - min(sent.values())) / 1e9 if got else float("inf")
            delivered = len(got) / span
            lost = len(sent) - len(got)
            label = "flat out" if rate is None else f"{rate:.0f} Hz"
            print(
                f"  {label:9s} {len(sent)} frames: delivered {delivered:6.0f} frames/s, lost {lost}"
            )
            if lost == 0:
                best = max(best, delivered)
        print(
            f"  highest loss-free rate: {best:.0f} frames/s ({best / 50:.0f}x the camera's 50 Hz)"
        )
        print("3. a real flight at --speed 0 (render + archive + bus)")
        real_flight(script, tmp)


if __name__ == "__main__":
    main()
