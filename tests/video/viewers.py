"""Video viewers for the tests: QGroundControl's GStreamer chain and PyAV, on real UDP ports,
and a flight that feeds a VideoStream camera-tick samples at wall-clock pace."""

from __future__ import annotations

import contextlib
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import psutil
from bus.helpers import make_sample

from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.video.stream import VideoStream

# What QGroundControl's VideoReceiver builds for a udp:// (H.264) URI.
QGC_CAPS = "application/x-rtp,media=video,clock-rate=90000,encoding-name=H264"
GROUND_SPEED_M_S = 20.0
ALTITUDE_M = 300.0  # the altitude of the AIR missions UC-300, FL-300 ...
Image = npt.NDArray[np.uint8]


def gst_launch() -> str:
    """The gst-launch-1.0 program (.ci/run installs Debian's GStreamer packages)."""
    path = shutil.which("gst-launch-1.0")
    assert path is not None, "gst-launch-1.0 is missing: apt-get install gstreamer1.0-tools"
    return path


class GstViewer:
    """``gst-launch-1.0 udpsrc ! rtpjitterbuffer ! rtph264depay ! avdec_h264``, QGC's chain;
    the decoded frames go as raw BGR into a file, read back by :meth:`frame`."""

    def __init__(self, port: int, width: int, height: int, folder: Path, name: str) -> None:
        self.path = folder / f"{name}.bgr"
        self.shape = (height, width, 3)
        self.frame_bytes = width * height * 3
        cmd = [
            gst_launch(), "udpsrc", f"port={port}", f"caps={QGC_CAPS}", "!", "rtpjitterbuffer",
            "!", "rtph264depay", "!", "avdec_h264", "!", "videoconvert", "!",
            "video/x-raw,format=BGR", "!", "filesink", f"location={self.path}",
            "buffer-mode=unbuffered",
        ]  # fmt: skip
        self.playing_at: float | None = None  # when gst-launch said the pipeline plays
        self.first_frame_at: float | None = None
        self.proc = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        )
        self.output: list[str] = []
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=self._watch, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.output.append(line)
            if self.playing_at is None and "to PLAYING" in line:
                self.playing_at = time.monotonic()

    def _watch(self) -> None:
        while self.proc.poll() is None and self.first_frame_at is None:
            if self.frames() > 0:
                self.first_frame_at = time.monotonic()
            time.sleep(0.005)

    def wait_playing(self, timeout_s: float = 60.0) -> float:
        """Wait until the pipeline plays (its socket is bound); when it did."""
        deadline = time.monotonic() + timeout_s
        while self.playing_at is None:
            assert self.proc.poll() is None, "".join(self.output)
            assert time.monotonic() < deadline, "gst-launch did not start playing"
            time.sleep(0.01)
        return self.playing_at

    def frames(self) -> int:
        """Frames decoded so far."""
        try:
            return self.path.stat().st_size // self.frame_bytes
        except FileNotFoundError:
            return 0

    def frame(self, index: int) -> Image:
        """Decoded frame ``index`` (negative: from the end)."""
        n = self.frames()
        i = index % n if index < 0 else index
        with self.path.open("rb") as f:
            f.seek(i * self.frame_bytes)
            data = f.read(self.frame_bytes)
        return np.frombuffer(data, np.uint8).reshape(self.shape)

    def close(self) -> None:
        """Stop gst-launch."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


@contextlib.contextmanager
def gst_viewer(
    port: int, width: int, height: int, folder: Path, name: str = "qgc"
) -> Iterator[GstViewer]:
    """A :class:`GstViewer`, stopped at the end."""
    viewer = GstViewer(port, width, height, folder, name)
    try:
        yield viewer
    finally:
        viewer.close()


def sdp_of(port: int) -> str:
    """The SDP FFmpeg needs to receive the stream (what the URI and the caps say)."""
    return (
        "v=0\no=- 0 0 IN IP4 127.0.0.1\ns=air-sitl\nc=IN IP4 127.0.0.1\nt=0 0\n"
        f"m=video {port} RTP/AVP 96\na=rtpmap:96 H264/90000\na=fmtp:96 packetization-mode=1\n"
    )


class PyavViewer:
    """FFmpeg's RTP receiver through PyAV: decoded frames with their RTP time (90 kHz ticks
    from the first packet received). It opens on its own thread, as FFmpeg's open reads the
    stream's first packets (or waits 10 s for them): send once :meth:`wait_listening`. The
    packets that open read are decoded too (no ``fflags nobuffer``, which drops them)."""

    def __init__(self, port: int, folder: Path) -> None:
        sdp = folder / f"stream-{port}.sdp"
        sdp.write_text(sdp_of(port), encoding="utf-8")
        self.port = port
        self.frames: list[tuple[int, Image]] = []
        self.error: BaseException | None = None
        self._stop = False
        self._container: Any = None
        self._thread = threading.Thread(target=self._run, args=(sdp,), daemon=True)
        self._thread.start()

    def _run(self, sdp: Path) -> None:
        import av  # the test side's own use of PyAV

        try:
            self._container = av.open(
                str(sdp),
                format="sdp",
                options={
                    "protocol_whitelist": "file,udp,rtp",
                    "reorder_queue_size": "0",
                    "max_delay": "0",
                },
                timeout=(60.0, 3.0),
            )
            for frame in self._container.decode(video=0):
                if frame.pts is not None:
                    self.frames.append((int(frame.pts), frame.to_ndarray(format="bgr24")))
                if self._stop:
                    return
        except Exception as err:  # the read timeout ends the stream
            self.error = err

    def wait_listening(self, timeout_s: float = 60.0) -> None:
        """Wait until FFmpeg's socket is bound to the port (this process's UDP sockets)."""
        deadline = time.monotonic() + timeout_s
        me = psutil.Process()
        sockets = getattr(me, "net_connections", None) or me.connections  # psutil < 6
        while not any(c.laddr and c.laddr.port == self.port for c in sockets("udp")):
            assert self._thread.is_alive(), repr(self.error)
            assert time.monotonic() < deadline, "FFmpeg did not bind its port"
            time.sleep(0.01)

    def close(self) -> None:
        """Stop reading and close the receiver."""
        self._stop = True
        self._thread.join(timeout=10)
        with contextlib.suppress(Exception):
            self._container.close()


def fly_east(
    stream: VideoStream,
    seconds: float,
    *,
    start_ns: int = 0,
    speed: float = 1.0,
    until: Callable[[], bool] = lambda: False,
) -> int:
    """Feed ``stream`` the camera ticks of a level flight east at wall-clock pace for
    ``seconds`` (or until ``until()``); the simulated time reached."""
    t0 = time.monotonic()
    t_ns = start_ns
    while (wall := time.monotonic() - t0) < seconds and not until():
        target = start_ns + int(wall * speed * 1e9)
        while t_ns <= target:
            east = GROUND_SPEED_M_S * t_ns / 1e9
            stream.on_sample(make_sample(t_ns, east_m=east, alt_agl_m=ALTITUDE_M))
            t_ns += CAMERA_PERIOD_NS
        time.sleep(0.002)
    return t_ns


def psnr(a: Image, b: Image) -> float:
    """Peak signal-to-noise ratio of two 8-bit images, in dB."""
    mse = float(np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2))
    return float("inf") if mse == 0 else 10 * np.log10(255.0**2 / mse)
