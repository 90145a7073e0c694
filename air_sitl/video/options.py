"""``serve``'s video options: where the stream goes, its frame rate, bitrate and overlay."""

from __future__ import annotations

import argparse
import re
from dataclasses import dataclass

from air_sitl.errors import OptionError

DEFAULT_VIDEO_HOST = "127.0.0.1"
DEFAULT_VIDEO_PORT = 5600  # QGroundControl's default UDP video port; instance N uses +N
DEFAULT_FPS = 30.0
DEFAULT_BITRATE_BPS = 6_000_000  # >= 30 dB PSNR over the urban map at 200-400 m
_URL = re.compile(r"^udp://(\[[0-9a-fA-F:.]+\]|[^:/\[\]]+):(\d{1,5})/?$")
_BITRATE = re.compile(r"^(\d+(?:\.\d+)?)([kKmM]?)$")


@dataclass(frozen=True, slots=True, kw_only=True)
class VideoOptions:
    """One RTP/H.264 stream: its destination and encoding."""

    host: str = DEFAULT_VIDEO_HOST
    port: int = DEFAULT_VIDEO_PORT
    fps: float = DEFAULT_FPS
    bitrate_bps: int = DEFAULT_BITRATE_BPS
    overlay: bool = False

    @property
    def url(self) -> str:
        """``udp://HOST:PORT`` as given to ``--video``."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"udp://{host}:{self.port}"

    @property
    def viewer_uri(self) -> str:
        """What a viewer on the destination host opens (VIDEO_STREAM_INFORMATION's ``uri``,
        as QGroundControl reads it: listen on every address at the port)."""
        return f"udp://0.0.0.0:{self.port}"


def add_video_arguments(parser: argparse.ArgumentParser) -> None:
    """``--video``, ``--no-video``, ``--video-fps``, ``--video-bitrate``, ``--video-overlay``."""
    g = parser.add_argument_group("video stream (RTP/H.264 over UDP, as PX4 SITL)")
    g.add_argument(
        "--video",
        default=None,
        metavar="udp://HOST:PORT",
        help="stream the downward camera here (default udp://127.0.0.1:5600, +N with "
        "--instance N; on whenever the camera is on)",
    )
    g.add_argument("--no-video", action="store_true", help="no video stream")
    g.add_argument(
        "--video-fps",
        default=str(DEFAULT_FPS),
        metavar="FPS",
        help=f"at most this many frames per wall-clock second (default {DEFAULT_FPS:g})",
    )
    g.add_argument(
        "--video-bitrate",
        default="6M",
        metavar="BPS",
        help="target bitrate in bit/s, k and M suffixes allowed (default 6M)",
    )
    g.add_argument(
        "--video-overlay",
        action="store_true",
        help="draw simulated time, altitude and GNSS state on the stream (default off: "
        "localizers may read the stream)",
    )


def parse_video_url(text: str) -> tuple[str, int]:
    """``udp://HOST:PORT`` -> (host, port)."""
    m = _URL.match(text.strip())
    if m is None:
        msg = f"--video {text!r}: expected udp://HOST:PORT (for example udp://127.0.0.1:5600)"
        raise OptionError(msg)
    port = int(m.group(2))
    if not 1 <= port <= 65535:
        msg = f"--video {text!r}: port {port} is not usable (expected 1..65535)"
        raise OptionError(msg)
    return m.group(1).strip("[]"), port


def parse_bitrate(text: str) -> int:
    """``4000000``, ``4000k`` or ``4M`` -> bits per second (100 kbit/s to 100 Mbit/s)."""
    m = _BITRATE.match(text.strip())
    scale = {"": 1, "k": 1_000, "m": 1_000_000}
    value = round(float(m.group(1)) * scale[m.group(2).lower()]) if m else 0
    if not 100_000 <= value <= 100_000_000:
        msg = f"--video-bitrate {text!r}: expected 100k..100M bit/s (for example 4M or 2500k)"
        raise OptionError(msg)
    return value


def parse_fps(text: str) -> float:
    """``--video-fps``: 1 to 60 frames per second (the camera renders at 50 Hz simulated)."""
    try:
        fps = float(text)
    except ValueError:
        fps = float("nan")
    if not 1.0 <= fps <= 60.0:
        msg = f"--video-fps {text!r}: expected a number of frames per second in 1..60"
        raise OptionError(msg)
    return fps


def video_options_from_args(
    args: argparse.Namespace, *, default_port: int = DEFAULT_VIDEO_PORT
) -> VideoOptions | None:
    """The stream the options ask for; None with ``--no-video``. ``default_port`` is the
    instance's port when ``--video`` is not given."""
    fps = parse_fps(str(args.video_fps))
    bitrate = parse_bitrate(str(args.video_bitrate))
    if args.no_video:
        if args.video is not None:
            msg = f"--no-video with --video {args.video}: give one of them"
            raise OptionError(msg)
        return None
    host, port = parse_video_url(args.video) if args.video else (DEFAULT_VIDEO_HOST, default_port)
    return VideoOptions(
        host=host, port=port, fps=fps, bitrate_bps=bitrate, overlay=bool(args.video_overlay)
    )
