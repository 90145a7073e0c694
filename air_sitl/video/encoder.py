"""H.264 in RTP over UDP with FFmpeg (through PyAV): the project's one import of ``av``.

libx264 encodes (constrained baseline, yuv420p, no B-frames, no look-ahead: a frame in, its
packets out); FFmpeg's RTP muxer packetizes as RFC 6184 (single NAL units, STAP-A for the
parameter sets, FU-A fragments; payload type 96; the marker bit on an access unit's last
packet) into datagrams of at most :data:`MAX_DATAGRAM_BYTES`. The muxer writes into this
module's socket, one datagram per packet, with its RTCP sender reports off: nothing goes to
PORT+1, which is the next vehicle's video port in a multi-vehicle session.

RTP timestamps are the simulation clock at 90 kHz (plus the muxer's random offset, as RFC 3550
asks). The sequence parameter sets come in-band before every keyframe (x264's repeated
headers), and a keyframe comes at least every :data:`KEYFRAME_PERIOD_S` of wall-clock time,
so a viewer that joins late decodes within a second.
"""

from __future__ import annotations

import contextlib
import io
import socket
import time
from fractions import Fraction
from typing import Any

import av
import numpy as np
import numpy.typing as npt

from air_sitl.errors import OptionError

MAX_DATAGRAM_BYTES = 1400  # RTP header included: fits any path MTU of 1500
PAYLOAD_TYPE = 96  # the first dynamic type, what QGroundControl's pipeline expects
RTP_CLOCK_HZ = 90_000
KEYFRAME_PERIOD_S = 0.45  # wall clock; with the viewer's jitter buffer, a picture within 1 s
NS_PER_S = 1_000_000_000


class _Datagrams(io.RawIOBase):
    """The muxer's output: every write is one RTP packet, sent as one UDP datagram."""

    def __init__(self, sock: socket.socket, address: tuple[str, int]) -> None:
        super().__init__()
        self._sock = sock
        self._address = address
        self.packets = 0
        self.bytes = 0
        self.largest = 0
        self.send_errors = 0

    def writable(self) -> bool:
        return True

    def write(self, data: Any) -> int:
        packet = bytes(data)
        try:
            self._sock.sendto(packet, self._address)
        except OSError:  # nobody listening (ICMP), a full buffer: a viewer sees a lost packet
            self.send_errors += 1
        self.packets += 1
        self.bytes += len(packet)
        self.largest = max(self.largest, len(packet))
        return len(packet)


class RtpH264Sender:
    """Encodes BGR frames and sends them as RTP/H.264 to ``host:port``."""

    def __init__(
        self,
        host: str,
        port: int,
        *,
        width_px: int,
        height_px: int,
        fps: float,
        bitrate_bps: int,
    ) -> None:
        if width_px % 2 or height_px % 2:
            msg = f"--video: the camera's {width_px}x{height_px} px must be even for yuv420p"
            raise OptionError(msg)
        family = socket.AF_INET6 if ":" in host else socket.AF_INET
        try:
            address = socket.getaddrinfo(host, port, family, socket.SOCK_DGRAM)[0][4]
        except OSError as err:
            msg = f"--video udp://{host}:{port}: cannot resolve {host!r} ({err})"
            raise OptionError(msg) from None
        self._sock = socket.socket(family, socket.SOCK_DGRAM)
        self._sock.setblocking(False)
        self.out = _Datagrams(self._sock, (str(address[0]), int(address[1])))
        self._container: Any = av.open(
            self.out,
            "w",
            format="rtp",
            options={"packetsize": str(MAX_DATAGRAM_BYTES), "rtpflags": "skip_rtcp"},
        )
        keyint = max(1, int(fps // 2))  # at full rate, a keyframe every half second
        self._stream: Any = self._container.add_stream(
            "libx264",
            rate=Fraction(fps).limit_denominator(1000),
            options={
                "preset": "ultrafast",
                "tune": "zerolatency",
                "profile": "baseline",
                "forced-idr": "1",
                # repeat-headers: SPS/PPS before every keyframe; force-cfr: rate control by
                # the frame rate, not by the simulated timestamps (at --speed 10 a frame spans
                # 1/3 s of simulated time but 1/30 s of the viewer's).
                "x264-params": f"keyint={keyint}:min-keyint={keyint}:scenecut=0:"
                "repeat-headers=1:force-cfr=1",
            },
        )
        ctx = self._stream.codec_context
        ctx.width, ctx.height = width_px, height_px
        ctx.pix_fmt = "yuv420p"
        ctx.bit_rate = bitrate_bps
        ctx.time_base = Fraction(1, RTP_CLOCK_HZ)
        ctx.thread_count = 1  # the frame's wall time is short; leave the cores to the flight
        self._time_base = ctx.time_base
        self._last_pts = -1
        self._last_key = -float("inf")
        self._force_key = True
        self.frames = 0
        self.keyframes = 0

    def request_keyframe(self) -> None:
        """Make the next frame a keyframe (a restarted stream)."""
        self._force_key = True

    def send(self, bgr: npt.NDArray[np.uint8], sim_time_ns: int) -> bool:
        """Encode one frame taken at ``sim_time_ns`` and send its packets; False when the
        time is not after the previous frame's (RTP timestamps only go forward)."""
        pts = sim_time_ns * RTP_CLOCK_HZ // NS_PER_S
        if pts <= self._last_pts:
            return False
        frame = av.VideoFrame.from_ndarray(bgr, format="bgr24").reformat(format="yuv420p")
        frame.pts = pts
        frame.time_base = self._time_base
        now = time.monotonic()
        if self._force_key or now - self._last_key >= KEYFRAME_PERIOD_S:
            frame.pict_type = av.video.frame.PictureType.I
            self._force_key = False
        for packet in self._stream.encode(frame):
            if packet.is_keyframe:
                self._last_key = now
                self.keyframes += 1
            self._container.mux(packet)
        self._last_pts = pts
        self.frames += 1
        return True

    def close(self) -> None:
        """Flush the encoder and close the socket (idempotent)."""
        container, self._container = self._container, None
        if container is None:
            return
        with contextlib.suppress(Exception):  # a flush error at exit is not the user's
            for packet in self._stream.encode(None):
                container.mux(packet)
        with contextlib.suppress(Exception):
            container.close()
        self._sock.close()
