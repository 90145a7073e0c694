"""serve's video stream: its CPU cost beside the render, its latency, and the simulation rate.

Usage: python benchmarks/bench_video.py [--frames 150] [--latency-seconds 8] [--speed-seconds 15]

- Cost: CPU time (this thread's) to encode and send a 640x480 frame (libx264 through PyAV,
  RTP packets to a loopback port), beside the floor of rendering the same frame over the urban
  map: the ratio says what the stream adds to the camera.
- Latency: from the moment a sample is handed to the stream to the moment FFmpeg's RTP
  receiver (PyAV, same process, the same FFmpeg decoder QGroundControl's avdec_h264 wraps) has
  decoded it: render, encode, UDP, depacketize, decode. Median and 90th percentile (target:
  median < 100 ms).
- Simulation rate: ``air-sitl serve --speed 10`` (real process, loopback) without and with the
  stream, simulated seconds per wall second from a pymavlink client's time_boot_ms over the same
  wall window; the run without video is the floor (target: within 10 %).

Print ``uptime`` beside the figures: the reference machine has 2 cores shared with others.
"""

from __future__ import annotations

import argparse
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(REPO), str(REPO / "tests"), str(REPO / "tests" / "video")]

from bus.helpers import HOME, make_sample  # noqa: E402
from pymavlink import mavutil  # noqa: E402
from viewers import Image, PyavViewer, psnr  # noqa: E402

from air_sitl.camera.model import CameraModel  # noqa: E402
from air_sitl.camera.render import Renderer  # noqa: E402
from air_sitl.clock import CAMERA_PERIOD_NS  # noqa: E402
from air_sitl.maps.open import open_map  # noqa: E402
from air_sitl.state import SimSample  # noqa: E402
from air_sitl.video.encoder import RtpH264Sender  # noqa: E402
from air_sitl.video.options import VideoOptions  # noqa: E402
from air_sitl.video.stream import VideoCamera, VideoStream  # noqa: E402

ALT_M, SPEED_M_S = 300.0, 20.0


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def cost(frames: int) -> None:
    """CPU ms per frame: render (floor) and encode + send."""
    renderer = Renderer(open_map("urban", HOME), CameraModel(), seed=1)
    samples = [
        make_sample(i * CAMERA_PERIOD_NS, east_m=SPEED_M_S * i * 0.02, alt_agl_m=ALT_M)
        for i in range(frames)
    ]
    images = []
    t0 = time.thread_time()
    for s in samples:
        images.append(renderer.render(s.state, noise_index=0))
    render_ms = (time.thread_time() - t0) / frames * 1e3
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sink:
        sink.bind(("127.0.0.1", 0))
        sender = RtpH264Sender(
            "127.0.0.1", sink.getsockname()[1], width_px=640, height_px=480, fps=30.0,
            bitrate_bps=VideoOptions().bitrate_bps,
        )  # fmt: skip
        t0 = time.thread_time()
        for s, image in zip(samples, images, strict=True):
            sender.send(image, s.state.sim_time_ns)
        encode_ms = (time.thread_time() - t0) / frames * 1e3
        sender.close()
    print(f"cost per 640x480 frame: render {render_ms:.2f} ms CPU (floor), encode+send "
          f"{encode_ms:.2f} ms CPU: ratio {encode_ms / render_ms:.2f}")  # fmt: skip


def latency(seconds: float) -> None:
    """Sample handed over -> frame decoded by FFmpeg's RTP receiver."""
    port = free_udp_port()
    renderer = Renderer(open_map("urban", HOME), CameraModel(), seed=1)
    taken: dict[int, float] = {}
    first_images: dict[int, Image] = {}  # to find which frame the receiver decoded first

    def render(sample: SimSample) -> Image:
        image = renderer.render(sample.state)
        if len(first_images) < 30:
            first_images[sample.state.sim_time_ns] = image.copy()
        return image

    with tempfile.TemporaryDirectory() as tmp:
        viewer = PyavViewer(port, Path(tmp))
        stream = VideoStream(
            VideoOptions(port=port),
            VideoCamera(width_px=640, height_px=480, hfov_deg=57.0),
            render,
            on_sent=lambda t_ns, at, _sent: taken.__setitem__(t_ns, at),
        )
        decoded: list[tuple[int, float]] = []
        first_decoded: Image | None = None
        seen = 0
        t0 = time.monotonic()
        t_ns = 0
        while time.monotonic() - t0 < seconds:
            target = int((time.monotonic() - t0) * 1e9)
            while t_ns <= target:
                stream.on_sample(make_sample(t_ns, east_m=SPEED_M_S * t_ns / 1e9, alt_agl_m=ALT_M))
                t_ns += CAMERA_PERIOD_NS
            now = time.monotonic()
            decoded.extend((pts, now) for pts, _ in viewer.frames[seen:])
            if first_decoded is None and viewer.frames:
                first_decoded = viewer.frames[0][1]
            seen = len(viewer.frames)
            time.sleep(0.001)
        stream.close()
        viewer.close()
    # The receiver's first frame is found among the first sent by its picture; RTP times from
    # it map to simulated times.
    assert first_decoded is not None, "nothing decoded"
    first_ns = max(first_images, key=lambda t: psnr(first_decoded, first_images[t]))
    pts0 = decoded[0][0]
    delays = []
    for pts, at in decoded:
        t = first_ns + round((pts - pts0) * 1e9 / 90_000 / 1e6) * 1_000_000
        if t in taken and t - first_ns > 1e9:  # after the receiver's start-up probing
            delays.append((at - taken[t]) * 1e3)
    delays.sort()
    print(f"latency sample -> decoded over {len(delays)} frames: median "
          f"{statistics.median(delays):.1f} ms, p90 {delays[int(0.9 * len(delays))]:.1f} ms "
          f"(target median < 100 ms); {stream.counters.frames_dropped} frames dropped")  # fmt: skip


def sim_rate(seconds: float, video: bool) -> float:
    """Simulated seconds per wall second of ``serve --speed 10``."""
    gcs_port = free_udp_port()
    args = ["--mavlink", f"udpout:127.0.0.1:{gcs_port}", "--speed", "10", "--quiet"]
    args += ["--video", f"udp://127.0.0.1:{free_udp_port()}"] if video else ["--no-video"]
    conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_port}", dialect="common")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    proc = subprocess.Popen([sys.executable, "-m", "air_sitl", "serve", *args], env=env)
    try:
        first: tuple[float, int] | None = None
        last: tuple[float, int] | None = None
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            msg = conn.recv_match(type="ATTITUDE", blocking=True, timeout=0.5)
            if msg is None:
                continue
            point = (time.monotonic(), int(msg.time_boot_ms))
            if first is None:
                if point[1] > 3000:  # past the start-up
                    first = point
                continue
            last = point
            if last[0] - first[0] >= seconds:
                break
        assert first is not None and last is not None, "no telemetry from serve"
        return (last[1] - first[1]) / 1e3 / (last[0] - first[0])
    finally:
        proc.terminate()
        proc.wait()
        conn.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=150)
    parser.add_argument("--latency-seconds", type=float, default=8.0)
    parser.add_argument("--speed-seconds", type=float, default=15.0)
    args = parser.parse_args()
    print("load:", os.getloadavg())
    cost(args.frames)
    latency(args.latency_seconds)
    floor = sim_rate(args.speed_seconds, video=False)
    with_video = sim_rate(args.speed_seconds, video=True)
    print(f"serve --speed 10: {floor:.2f} sim s / wall s without video (floor), "
          f"{with_video:.2f} with: ratio {with_video / floor:.3f} (target >= 0.90)")  # fmt: skip
    print("load:", os.getloadavg())


if __name__ == "__main__":
    main()
