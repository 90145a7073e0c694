"""The camera component (MAV_COMP_ID_CAMERA = 100) of the vehicle, as on a PX4 vehicle with a
MAVLink camera: its own HEARTBEAT (MAV_TYPE_CAMERA) on every link, and the camera protocol
commands addressed to it answered from it (CAMERA_INFORMATION of the simulated camera;
IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE open and close the capture window).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Encoder, Message, mav
from air_sitl.mavlink.commands import run_then_ack
from air_sitl.mavlink.interfaces import AutopilotLike, outcome, whole
from air_sitl.mavlink.links import Channel, Link

if TYPE_CHECKING:
    from air_sitl.mavlink.codec import Signing
    from air_sitl.mavlink.vehicle import VehicleEndpoint

COMPONENT_ID = mav.MAV_COMP_ID_CAMERA


class CameraComponent:
    """Speaks as component 100 of the vehicle's system on every link."""

    def __init__(self, ep: VehicleEndpoint, camera: tm.CameraInfo) -> None:
        self._ep = ep
        self.camera = camera
        self._encoders: dict[Link, Encoder] = {}

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
        """A message addressed to the camera: its commands get one COMMAND_ACK each."""
        if msg.get_type() not in ("COMMAND_LONG", "COMMAND_INT"):
            return
        cmd = msg.command
        asked = whole(msg.param1)
        info = mav.MAVLINK_MSG_ID_CAMERA_INFORMATION
        if cmd == mav.MAV_CMD_REQUEST_CAMERA_INFORMATION or (
            cmd == mav.MAV_CMD_REQUEST_MESSAGE and asked == info
        ):
            latest = self._ep.latest
            sim_ns = latest.state.sim_time_ns if latest is not None else 0
            self._ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
            self.reply(ch, tm.camera_information(sim_ns, self.camera))
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE and asked == mav.MAVLINK_MSG_ID_HEARTBEAT:
            self._ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
            self.reply(ch, tm.camera_heartbeat())
        elif cmd in (mav.MAV_CMD_IMAGE_START_CAPTURE, mav.MAV_CMD_IMAGE_STOP_CAPTURE):
            self._capture(ch, msg, start=cmd == mav.MAV_CMD_IMAGE_START_CAPTURE)
        else:
            self._ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)

    def _capture(self, ch: Channel, msg: Message, *, start: bool) -> None:
        def capture(ap: AutopilotLike) -> tuple[int, str]:
            ok, _reason = outcome(ap.start_capture() if start else ap.stop_capture())
            return (mav.MAV_RESULT_ACCEPTED if ok else mav.MAV_RESULT_DENIED), ""

        run_then_ack(self._ep, capture, lambda result, _text: self._ack(ch, msg, result))
