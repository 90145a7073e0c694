"""The camera component (MAV_COMP_ID_CAMERA = 100) of the vehicle, as on a PX4 vehicle with a
MAVLink camera: its own HEARTBEAT (MAV_TYPE_CAMERA) on every link, and the camera protocol
commands addressed to it answered from it: CAMERA_INFORMATION of the simulated camera,
CAMERA_SETTINGS, CAMERA_CAPTURE_STATUS; IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE open and close
the capture window. With a video stream, the video protocol as QGroundControl and MAVSDK use
it: CAMERA_INFORMATION flags HAS_VIDEO_STREAM; VIDEO_STREAM_INFORMATION and VIDEO_STREAM_STATUS
of stream 1 (stream id 0 asks for all) by MAV_CMD_REQUEST_MESSAGE and by the legacy request
commands; VIDEO_START_STREAMING / VIDEO_STOP_STREAMING start and stop it.

A stream id left unset (NaN, as MAVSDK sends a parameter it does not use) is 0, all streams:
common.xml's default for an unused MAV_CMD_REQUEST_MESSAGE parameter. CAMERA_INFORMATION of a
camera with a stream is followed by the stream's VIDEO_STREAM_INFORMATION: MAVSDK (4.1) asks
for it only every 20 s (CameraImpl::request_slower) and takes it unasked from a camera it has
heard, so its camera plugin lists the stream with the camera rather than up to 20 s later.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Encoder, Message, mav
from air_sitl.mavlink.commands import run_then_ack
from air_sitl.mavlink.interfaces import (
    AutopilotLike,
    EndpointLike,
    VideoStreamLike,
    outcome,
    whole,
)
from air_sitl.mavlink.links import Channel, Link

if TYPE_CHECKING:
    from air_sitl.mavlink.codec import Signing

COMPONENT_ID = mav.MAV_COMP_ID_CAMERA
_CAMERA_MODES = (mav.CAMERA_MODE_IMAGE, mav.CAMERA_MODE_VIDEO)


class CameraComponent:
    """Speaks as component 100 of the vehicle's system on every link."""

    def __init__(
        self, ep: EndpointLike, camera: tm.CameraInfo, video: VideoStreamLike | None = None
    ) -> None:
        self._ep = ep
        self.camera = camera
        self.video = video
        self.mode_id = mav.CAMERA_MODE_IMAGE
        self._encoders: dict[Link, Encoder] = {}
        # MAV_CMD_REQUEST_MESSAGE's message id -> what answers it (param2: the stream id).
        self._requested = {
            mav.MAVLINK_MSG_ID_CAMERA_INFORMATION: self._information,
            mav.MAVLINK_MSG_ID_HEARTBEAT: lambda _stream: [tm.camera_heartbeat()],
            mav.MAVLINK_MSG_ID_CAMERA_SETTINGS: self._settings,
            mav.MAVLINK_MSG_ID_CAMERA_CAPTURE_STATUS: self._capture_status,
            mav.MAVLINK_MSG_ID_VIDEO_STREAM_INFORMATION: self._stream_information,
            mav.MAVLINK_MSG_ID_VIDEO_STREAM_STATUS: self._stream_status,
        }
        # The legacy request commands: the message they ask for (param1: the stream id).
        self._legacy = {
            mav.MAV_CMD_REQUEST_CAMERA_INFORMATION: self._information,
            mav.MAV_CMD_REQUEST_CAMERA_SETTINGS: self._settings,
            mav.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS: self._capture_status,
            mav.MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION: self._stream_information,
            mav.MAV_CMD_REQUEST_VIDEO_STREAM_STATUS: self._stream_status,
        }

    def open(self, links: tuple[Link, ...], signing: Signing | None) -> None:
        """One encoder (sequence numbers) per link for this component."""
        for link in links:
            self._encoders[link] = Encoder(self._ep.options.system_id, COMPONENT_ID, signing)

    def broadcast(self, msg: Message) -> None:
        """Send from the camera to every peer of every link."""
        for link, encoder in self._encoders.items():
            link.send(encoder.encode(msg))

    def reply(self, ch: Channel, msg: Message) -> None:
        """Send from the camera to one peer."""
        encoder = self._encoders.get(ch.link)
        if encoder is not None:
            ch.link.send(encoder.encode(msg), ch)

    def send_heartbeat(self) -> None:
        """The camera's HEARTBEAT (with the autopilot's, every wall-clock second)."""
        self.broadcast(tm.camera_heartbeat())

    def _ack(self, ch: Channel, msg: Message, result: int) -> None:
        ack = mav.MAVLink_command_ack_message(
            msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        self.reply(ch, ack)

    def on_message(self, ch: Channel, msg: Message) -> None:
        """A message addressed to the camera: its commands get one COMMAND_ACK each, then the
        messages they ask for."""
        if msg.get_type() not in ("COMMAND_LONG", "COMMAND_INT"):
            return
        cmd = msg.command
        if cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            answer = self._requested.get(whole(msg.param1))
            self._answer(ch, msg, None if answer is None else answer(_index(msg.param2)))
        elif cmd in self._legacy:
            self._answer(ch, msg, self._legacy[cmd](_index(msg.param1)))
        elif cmd in (mav.MAV_CMD_IMAGE_START_CAPTURE, mav.MAV_CMD_IMAGE_STOP_CAPTURE):
            self._capture(ch, msg, start=cmd == mav.MAV_CMD_IMAGE_START_CAPTURE)
        elif cmd in (mav.MAV_CMD_VIDEO_START_STREAMING, mav.MAV_CMD_VIDEO_STOP_STREAMING):
            self._ack(ch, msg, self._streaming(msg, start=cmd == mav.MAV_CMD_VIDEO_START_STREAMING))
        elif cmd == mav.MAV_CMD_SET_CAMERA_MODE:
            self._ack(ch, msg, self._set_mode(whole(msg.param2)))
        else:
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)

    def _answer(self, ch: Channel, msg: Message, answer: list[Message] | int | None) -> None:
        """ACCEPTED then the messages; UNSUPPORTED for a message this camera does not have;
        a MAV_RESULT as it is (DENIED for a stream id that is not ours)."""
        if answer is None:
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
        elif isinstance(answer, int):
            self._ack(ch, msg, answer)
        else:
            self._ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
            for reply in answer:
                self.reply(ch, reply)

    def _sim_ns(self) -> int:
        latest = self._ep.latest
        return latest.state.sim_time_ns if latest is not None else 0

    def _information(self, _param: int) -> list[Message]:
        """CAMERA_INFORMATION, then the stream's VIDEO_STREAM_INFORMATION when there is one."""
        info = tm.camera_information(self._sim_ns(), self.camera, video=self.video is not None)
        stream = self._stream_information(0)
        return [info, *stream] if isinstance(stream, list) else [info]

    def _settings(self, _param: int) -> list[Message]:
        return [tm.camera_settings(self._sim_ns(), self.mode_id)]

    def _capture_status(self, _param: int) -> list[Message]:
        latest = self._ep.latest
        capturing = latest is not None and latest.autopilot.capturing
        status = tm.camera_capture_status(
            self._sim_ns(), capturing=capturing, images=self._ep.images_captured
        )
        return [status]

    def _video_info(self, stream_id: int) -> tm.VideoStreamInfo | int | None:
        """The stream's description for ``stream_id`` (0: all), or why not."""
        video = self.video
        if video is None:
            return None
        if stream_id not in (0, tm.VIDEO_STREAM_ID):
            return int(mav.MAV_RESULT_DENIED)
        return tm.VideoStreamInfo(
            running=video.streaming, fps=video.fps, bitrate_bps=video.bitrate_bps, uri=video.uri
        )

    def _stream_information(self, stream_id: int) -> list[Message] | int | None:
        info = self._video_info(stream_id)
        if not isinstance(info, tm.VideoStreamInfo):
            return info
        return [tm.video_stream_information(self.camera, info)]

    def _stream_status(self, stream_id: int) -> list[Message] | int | None:
        info = self._video_info(stream_id)
        if not isinstance(info, tm.VideoStreamInfo):
            return info
        return [tm.video_stream_status(self.camera, info)]

    def _streaming(self, msg: Message, *, start: bool) -> int:
        """Start or stop the stream (param1: stream id, 0 = all); the status follows."""
        if self.video is None:
            return int(mav.MAV_RESULT_UNSUPPORTED)
        if _index(msg.param1) not in (0, tm.VIDEO_STREAM_ID):
            return int(mav.MAV_RESULT_DENIED)
        if start:
            self.video.start()
        else:
            self.video.stop()
        return int(mav.MAV_RESULT_ACCEPTED)

    def _set_mode(self, mode_id: int) -> int:
        """Image or video mode (both at once here: the camera captures and streams)."""
        if mode_id not in _CAMERA_MODES:
            return int(mav.MAV_RESULT_DENIED)
        self.mode_id = mode_id
        return int(mav.MAV_RESULT_ACCEPTED)

    def _capture(self, ch: Channel, msg: Message, *, start: bool) -> None:
        def capture(ap: AutopilotLike) -> tuple[int, str]:
            ok, _reason = outcome(ap.start_capture() if start else ap.stop_capture())
            return (mav.MAV_RESULT_ACCEPTED if ok else mav.MAV_RESULT_DENIED), ""

        run_then_ack(self._ep, capture, lambda result, _text: self._ack(ch, msg, result))


def _index(value: float) -> int:
    """A stream id parameter: NaN (left unset) is 0, all streams; other values as ``whole``."""
    return 0 if math.isnan(value) else whole(value)
