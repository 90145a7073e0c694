"""The video stream leaves the archives alone: serve's recorder writes the same bytes with and
without the stream (the stream renders with a renderer of its own and only reads samples)."""

from __future__ import annotations

import socket
from pathlib import Path

from bus.helpers import HOME
from ports import free_port
from short_plans import write_short_plan

from air_sitl.builder import build_flight, load_setup, open_camera, open_setup_map
from air_sitl.camera.model import CameraModel
from air_sitl.options import FlightOptions
from air_sitl.recording import CaptureRecorder
from air_sitl.serving import open_video
from air_sitl.sinks import Sink
from air_sitl.video.options import VideoOptions
from air_sitl.video.stream import VideoStream


def _record(plan: Path, out: Path, video_port: int | None) -> VideoStream | None:
    """Fly ``plan`` as serve records it (a CaptureRecorder per capture window), with or
    without the video stream among the sinks, at --speed 8: seconds of wall time for the
    stream to send frames in (the pacing only waits: the same steps at any speed)."""
    setup = load_setup(
        plan,
        FlightOptions(air_start=True, seed=7, speed=8.0),
        camera=CameraModel(width_px=160, height_px=120),
        render_workers=2,  # frames lag the samples: the archive must not depend on how much
    )
    recorder = CaptureRecorder(out, setup)
    sinks: list[Sink] = [recorder]
    stream = None
    if video_port is not None:
        stream = open_video(setup, VideoOptions(port=video_port, fps=60.0))
        sinks.append(stream)
    camera = open_camera(setup, open_setup_map(setup))
    flight = build_flight(setup, sinks=sinks, camera=camera)
    recorder.autopilot = flight.autopilot
    flight.run(stop=lambda s: s.autopilot.mission_completed, max_sim_time_ns=600 * 10**9)
    return stream


def _files(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in root.rglob("*") if p.is_file()}


def test_archives_are_the_same_bytes_with_and_without_video(tmp_path: Path) -> None:
    plan = write_short_plan(tmp_path / "short.plan", HOME, leg_m=60.0)
    port = free_port(socket.SOCK_DGRAM)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as viewer:
        viewer.bind(("127.0.0.1", port))  # a listener, so that sending never errs
        stream = _record(plan, tmp_path / "with", port)
    _record(plan, tmp_path / "without", None)
    assert stream is not None
    assert stream.counters.frames_sent > 10, stream.counters  # it really streamed
    with_video, without = _files(tmp_path / "with"), _files(tmp_path / "without")
    assert any(name.endswith(".jpg") for name in without)
    assert with_video.keys() == without.keys()
    differ = [n for n in without if with_video[n] != without[n]]
    assert differ == [], differ
