"""The video stream as a Sink: picks frames from the simulation, encodes them on its own thread.

At every camera tick (50 Hz of simulated time) the simulation thread asks one question: is a
video frame due by the wall clock (at most ``fps`` a second, whatever ``--speed``)? If so it
leaves the sample in a one-slot mailbox and goes on; the video thread renders the camera's
view of that sample with a renderer of its own (the archive's camera is not touched, so
archives are the same bytes with and without video), draws the optional overlay, encodes and
sends. When the thread is still busy with the previous frame, the waiting sample is replaced by
the newer one and counted as dropped: the stream shows the latest view and never slows the
flight. RTP timestamps are the samples' simulated times.

MAVLink's video protocol reads and drives it through ``streaming``, :meth:`start` and
:meth:`stop` and the description properties (``air_sitl.mavlink.interfaces.VideoStreamLike``).
"""

from __future__ import annotations

import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import GpsFix, SimSample
from air_sitl.video.encoder import RtpH264Sender
from air_sitl.video.options import VideoOptions
from air_sitl.video.overlay import draw_overlay

RenderFn = Callable[[SimSample], npt.NDArray[np.uint8]]
# Told of every frame sent: (simulated time ns, wall time its sample was taken, wall time sent).
SentFn = Callable[[int, float, float], None]
MAX_REPORTED_ERRORS = 3


@dataclass(frozen=True, slots=True, kw_only=True)
class VideoCamera:
    """What the stream says of its camera (VIDEO_STREAM_INFORMATION)."""

    width_px: int
    height_px: int
    hfov_deg: float
    name: str = "air-sitl downward camera"


@dataclass(slots=True)
class VideoCounters:
    """What the stream did, printed when serve stops."""

    frames_sent: int = 0
    frames_dropped: int = 0  # due but replaced by a newer one: the encoder was behind
    errors: int = 0


class VideoStream(NullSink):
    """An RTP/H.264 stream of the camera's view, fed by the flight (a Sink)."""

    def __init__(
        self,
        options: VideoOptions,
        camera: VideoCamera,
        render: RenderFn,
        *,
        on_close: Callable[[], None] = lambda: None,
        on_sent: SentFn | None = None,
    ) -> None:
        self.options = options
        self.camera = camera
        self._render = render
        self._on_close = on_close
        self._on_sent = on_sent
        self._sender = RtpH264Sender(
            options.host,
            options.port,
            width_px=camera.width_px,
            height_px=camera.height_px,
            fps=options.fps,
            bitrate_bps=options.bitrate_bps,
        )
        self._period_s = 1.0 / options.fps
        self._next_due = -float("inf")
        self._gps: GpsFix | None = None
        self._cond = threading.Condition()
        self._pending: tuple[SimSample, GpsFix | None, float] | None = None
        self._streaming = True
        self._closed = False
        self.counters = VideoCounters()
        self._thread = threading.Thread(target=self._run, name="video", daemon=True)
        self._thread.start()

    # --- what the MAVLink camera component reads and drives -------------------------------

    @property
    def streaming(self) -> bool:
        """Frames are being sent (VIDEO_STREAM_STATUS_FLAGS_RUNNING)."""
        return self._streaming and not self._closed

    def start(self) -> None:
        """Start (again) sending frames, from a keyframe (MAV_CMD_VIDEO_START_STREAMING)."""
        with self._cond:
            if not self._streaming:
                self._sender.request_keyframe()
                self._next_due = -float("inf")
            self._streaming = True

    def stop(self) -> None:
        """Stop sending frames (MAV_CMD_VIDEO_STOP_STREAMING); a frame being encoded ends."""
        with self._cond:
            self._streaming = False
            self._pending = None

    @property
    def uri(self) -> str:
        """Where a viewer on the destination host listens."""
        return self.options.viewer_uri

    @property
    def fps(self) -> float:
        """The most frames a wall-clock second."""
        return self.options.fps

    @property
    def bitrate_bps(self) -> int:
        """The encoder's target bitrate."""
        return self.options.bitrate_bps

    @property
    def datagrams_sent(self) -> int:
        """RTP packets sent so far."""
        return self._sender.out.packets

    # --- Sink -----------------------------------------------------------------------------

    def on_sample(self, sample: SimSample) -> None:
        """Keep the latest fix; at a camera tick, hand the sample over if a frame is due."""
        if sample.gps is not None:
            self._gps = sample.gps
        if sample.state.sim_time_ns % CAMERA_PERIOD_NS or not self._streaming:
            return
        now = time.monotonic()
        if now < self._next_due:
            return
        # Keep the cadence (ticks come every 20 ms at --speed 1: 30 fps is 2 ticks of 3)
        # unless a whole period was missed: then start again from now, no burst.
        late = now - self._next_due
        self._next_due = (self._next_due if late < self._period_s else now) + self._period_s
        with self._cond:
            if not self._streaming:
                return
            if self._pending is not None:
                self.counters.frames_dropped += 1
            self._pending = (sample, self._gps, now)
            self._cond.notify()

    def close(self, result: FlightResult | None = None) -> None:
        """Stop the thread (the frame under way is finished), flush, close the socket."""
        with self._cond:
            if self._closed:
                return
            self._closed = True
            self._cond.notify()
        self._thread.join(timeout=10.0)
        self._sender.close()
        self._on_close()

    # --- the video thread -----------------------------------------------------------------

    def _run(self) -> None:
        while True:
            with self._cond:
                while self._pending is None and not self._closed:
                    self._cond.wait()
                if self._closed or self._pending is None:
                    return
                sample, gps, taken = self._pending
                self._pending = None
            try:
                self._send(sample, gps, taken)
            except Exception:
                self.counters.errors += 1
                if self.counters.errors <= MAX_REPORTED_ERRORS:
                    print("air-sitl: video frame failed:", file=sys.stderr)
                    traceback.print_exc(file=sys.stderr)

    def _send(self, sample: SimSample, gps: GpsFix | None, taken: float) -> None:
        image = self._render(sample)
        if self.options.overlay:
            draw_overlay(image, sample, gps)
        if not self._streaming:
            return
        if self._sender.send(image, sample.state.sim_time_ns):
            self.counters.frames_sent += 1
            if self._on_sent is not None:
                self._on_sent(sample.state.sim_time_ns, taken, time.monotonic())
