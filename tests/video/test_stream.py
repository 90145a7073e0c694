"""The video stream in-process: the real encoder and muxer, real UDP on loopback, decoded by
QGroundControl's GStreamer chain and by PyAV; packets checked as QGC's depayloader reads them."""

from __future__ import annotations

import itertools
import socket
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from bus.helpers import HOME, SAFETY_S, make_sample
from ports import free_port
from viewers import Image, PyavViewer, fly_east, gst_viewer, psnr

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.maps.open import open_map
from air_sitl.state import SimSample
from air_sitl.video.encoder import KEYFRAME_PERIOD_S, MAX_DATAGRAM_BYTES, PAYLOAD_TYPE
from air_sitl.video.options import VideoOptions
from air_sitl.video.stream import VideoCamera, VideoStream

pytestmark = pytest.mark.integration
WIDTH, HEIGHT = 640, 480  # the camera's default size
SO_TIMESTAMPNS = 35  # Linux's socket option: each datagram's arrival time (not in Python's socket)
ENCODE_TOLERANCE_S = 0.1  # how much one frame's encoding may take longer than another's


class Rendered:
    """The urban map as the camera sees it; every rendered frame kept by simulated time."""

    def __init__(self, width: int = WIDTH, height: int = HEIGHT) -> None:
        self.renderer = Renderer(
            open_map("urban", HOME), CameraModel(width_px=width, height_px=height), seed=3
        )
        self.by_time: dict[int, Image] = {}
        self.delay_s = 0.0

    def __call__(self, sample: SimSample) -> Image:
        if self.delay_s:
            time.sleep(self.delay_s)
        image = self.renderer.render(sample.state)
        self.by_time[sample.state.sim_time_ns] = image.copy()
        return image


def open_stream(port: int, render: Rendered, **options: float) -> VideoStream:
    cam = render.renderer.camera
    return VideoStream(
        VideoOptions(port=port, **options),  # type: ignore[arg-type]
        VideoCamera(width_px=cam.width_px, height_px=cam.height_px, hfov_deg=cam.hfov_deg),
        render,
    )


def test_qgc_pipeline_decodes_and_a_viewer_joining_late_sees_a_picture_within_a_second(
    tmp_path: Path,
) -> None:
    port = free_port(socket.SOCK_DGRAM)
    render = Rendered()
    stream = open_stream(port, render)
    try:
        t_ns = fly_east(stream, 2.0)  # nobody listening yet: four keyframe periods go by
        with gst_viewer(port, WIDTH, HEIGHT, tmp_path) as late:
            joined = late.wait_playing()
            fly_east(stream, 60.0, start_ns=t_ns, until=lambda: late.frames() >= 60)
            assert late.first_frame_at is not None, "".join(late.output)
            assert late.first_frame_at - joined < 1.0
            assert late.frames() >= 60
            last = late.frame(-1)
    finally:
        stream.close()
    assert stream.counters.errors == 0
    # A picture, not a grey or black screen: the urban map's texture.
    assert float(last.std()) > 20.0


def test_decoded_frames_match_the_rendered_ones_at_the_default_bitrate(tmp_path: Path) -> None:
    port = free_port(socket.SOCK_DGRAM)
    render = Rendered()
    viewer = PyavViewer(port, tmp_path)
    viewer.wait_listening()  # before the first packet
    stream = open_stream(port, render)
    try:
        fly_east(stream, 4.0)
        time.sleep(0.5)
    finally:
        stream.close()
        viewer.close()
    assert len(viewer.frames) >= 60, viewer.error
    sent = sorted(render.by_time)
    # The first decoded frame is one of the first sent; its RTP time anchors the rest: every
    # later frame's RTP time is a simulated time a frame was rendered at (90 kHz ticks).
    pts0, first = viewer.frames[0]
    t0 = max(sent[:10], key=lambda t: psnr(first, render.by_time[t]))
    scores = []
    for pts, image in viewer.frames:
        t_ns = t0 + round((pts - pts0) * 1e9 / 90_000 / 1e6) * 1_000_000
        assert t_ns in render.by_time, f"RTP time {pts} is no rendered frame's simulated time"
        scores.append(psnr(image, render.by_time[t_ns]))
    assert min(scores) >= 30.0, f"PSNR min {min(scores):.1f} dB, median {np.median(scores):.1f}"


def keyframes(got: list[tuple[float, bytes]]) -> tuple[list[float], dict[int, set[int]]]:
    """When each keyframe's first packet came (IDR, NAL 5), and the NAL unit types of each
    access unit by its RTP time stamp."""
    keys: list[float] = []
    nals_by_stamp: dict[int, set[int]] = {}
    for at, p in got:
        nals = nals_by_stamp.setdefault(int.from_bytes(p[4:8], "big"), set())
        kind = p[12] & 0x1F
        if kind == 24:  # STAP-A: several NAL units
            i = 13
            while i + 2 < len(p):
                size = int.from_bytes(p[i : i + 2], "big")
                nals.add(p[i + 2] & 0x1F)
                i += 2 + size
        elif kind == 28:  # FU-A: the fragmented unit's type in the FU header
            nals.add(p[13] & 0x1F)
            if p[13] & 0x80 and p[13] & 0x1F == 5:
                keys.append(at)
        else:
            nals.add(kind)
            if kind == 5:
                keys.append(at)
    return keys, nals_by_stamp


def test_packets_are_what_qgc_reads_and_nothing_goes_to_the_next_port() -> None:
    port = free_port(socket.SOCK_DGRAM)
    rtp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rtp.bind(("127.0.0.1", port))
    rtcp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rtcp.bind(("127.0.0.1", port + 1))  # the next vehicle's video port
    got: list[tuple[float, bytes]] = []
    stop = threading.Event()

    # Each datagram stamped by the kernel as it arrives (loopback: when it was sent), not when
    # this thread gets to read it: a loaded machine delays the reader, not the stamps.
    rtp.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)

    def receive() -> None:
        rtp.settimeout(0.1)
        while not stop.is_set():
            try:
                data, ancillary, _, _ = rtp.recvmsg(65536, socket.CMSG_SPACE(16))
            except TimeoutError:
                continue
            sec, nsec = struct.unpack("qq", ancillary[0][2][:16])
            got.append((sec + nsec * 1e-9, data))

    reader = threading.Thread(target=receive, daemon=True)
    reader.start()
    render = Rendered(320, 240)
    stream = open_stream(port, render)
    seen = [0, 0]  # packets read, keyframes among them

    def seven_keyframes() -> bool:
        new = got[seen[0] :]
        seen[0] += len(new)
        seen[1] += len(keyframes(new)[0])
        return seen[1] >= 7

    try:  # until seven keyframes have come (the encoder starts slowly on a loaded machine)
        fly_east(stream, SAFETY_S, until=seven_keyframes)
    finally:
        stream.close()
        time.sleep(0.3)
        stop.set()
        reader.join()
    rtcp.settimeout(0.2)
    with pytest.raises(TimeoutError):
        rtcp.recv(65536)
    rtp.close()
    rtcp.close()
    packets = [p for _, p in got]
    assert packets and all(len(p) <= MAX_DATAGRAM_BYTES for p in packets)
    assert all(p[0] >> 6 == 2 and p[1] & 0x7F == PAYLOAD_TYPE for p in packets)
    # One marker bit per access unit: the last packet of each frame.
    stamps = [int.from_bytes(p[4:8], "big") for p in packets]
    markers = [p for p in packets if p[1] & 0x80]
    assert len(markers) == stream.counters.frames_sent == len(set(stamps))
    # Keyframes (IDR, NAL 5) come with SPS (7) and PPS (8) of the same access unit; a frame is
    # a keyframe once KEYFRAME_PERIOD_S of wall time have passed since the last one (encoder.py):
    # the frame before each keyframe was sent less than the period after the previous one, and
    # no keyframe comes sooner. The stamps are the sends to within one frame's encoding (a
    # tolerance): how often frames come is the loaded machine's, the rule is the encoder's.
    keys, nals_by_stamp = keyframes(got)
    for nals in nals_by_stamp.values():
        if 5 in nals:
            assert {7, 8} <= nals
    assert len(keys) >= 6
    assert KEYFRAME_PERIOD_S <= 0.5  # a late viewer decodes within a second (encoder.py)
    units = sorted({at for at, p in got if p[1] & 0x80})  # each access unit's last packet
    for k1, k2 in itertools.pairwise(keys):
        before = max(at for at in units if at < k2)
        assert before - k1 < KEYFRAME_PERIOD_S + ENCODE_TOLERANCE_S, (k1, before, k2)
        assert k2 - k1 > KEYFRAME_PERIOD_S - ENCODE_TOLERANCE_S, (k1, k2)
    print("keyframe gaps (s):", np.round(np.diff(keys), 3))
    # The profile: constrained baseline (profile_idc 66) in the SPS.
    sps = next(p for p in packets if p[12] & 0x1F == 24)
    assert sps[13 + 2] & 0x1F == 7 and sps[13 + 3] == 66


def test_stop_sends_nothing_and_start_resumes_with_a_keyframe() -> None:
    port = free_port(socket.SOCK_DGRAM)
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", port))
    rx.settimeout(0.5)
    render = Rendered(320, 240)
    stream = open_stream(port, render)
    try:
        t_ns = fly_east(stream, 1.0)
        stream.stop()
        assert not stream.streaming
        time.sleep(0.3)
        rx.settimeout(0.0)
        with pytest.raises(BlockingIOError):
            while True:
                rx.recv(65536)  # what was under way before the stop
        t_ns = fly_east(stream, 1.5, start_ns=t_ns)
        with pytest.raises(BlockingIOError):
            rx.recv(65536)
        stream.start()
        rx.settimeout(10.0)
        fly_east(stream, 30.0, start_ns=t_ns, until=lambda: stream.counters.frames_sent > 30)
        first = rx.recv(65536)
        assert first[12] & 0x1F == 24  # STAP-A with SPS/PPS: a keyframe starts the stream
    finally:
        stream.close()
        rx.close()


def test_an_encoder_behind_drops_frames_counts_them_and_never_slows_the_flight() -> None:
    port = free_port(socket.SOCK_DGRAM)
    render = Rendered(320, 240)
    render.delay_s = 0.2  # a frame every 0.2 s at most: 5 fps of the 30 asked
    stream = open_stream(port, render)
    slowest = 0.0
    try:
        t0 = time.monotonic()
        t_ns = 0
        while time.monotonic() - t0 < 3.0:
            sample_at = time.monotonic()
            stream.on_sample(make_sample(t_ns))
            slowest = max(slowest, time.monotonic() - sample_at)
            t_ns += 20_000_000
            time.sleep(0.02)
    finally:
        stream.close()
    c = stream.counters
    assert c.frames_dropped >= 40 and c.frames_sent <= 20
    assert slowest < 0.1  # the flight's thread never waits for the encoder
