"""COMMAND_LONG / COMMAND_INT and the other vehicle-control messages (SET_MODE,
MISSION_SET_CURRENT, TIMESYNC): every command gets exactly one COMMAND_ACK.

The autopilot proxies no camera: the camera is component 100 (camera.py), so requests for
camera messages addressed to the autopilot are UNSUPPORTED. (The camera protocol has an
autopilot answer CAMERA_INFORMATION only for the non-MAVLink cameras it proxies; MAVSDK takes
any component that answers it for a camera, and listed the autopilot as a second one.)
"""

from __future__ import annotations

import math
import sys
import time
import traceback
from collections.abc import Callable
from typing import Any

from air_sitl.errors import AirSitlError
from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Message, mav
from air_sitl.mavlink.interfaces import (
    SEVERITY_CRITICAL,
    SEVERITY_INFO,
    AutopilotLike,
    EndpointLike,
    EndpointPart,
    Handler,
    outcome,
    whole,
)
from air_sitl.mavlink.links import Channel
from air_sitl.mission.items import MissionType
from air_sitl.state import FlightMode

SimCommand = Callable[[AutopilotLike], tuple[int, str]]  # -> (MAV_RESULT, STATUSTEXT or "")


def run_then_ack(ep: EndpointLike, fn: SimCommand, ack: Callable[[int, str], None]) -> None:
    """Run an autopilot command on the simulation thread, then ``ack(result, text)`` on the I/O
    thread: TEMPORARILY_REJECTED at once without an autopilot, DENIED when the command raises
    an AirSitlError, FAILED (and the traceback on stderr) when it raises anything else."""
    if ep.autopilot is None:
        ack(mav.MAV_RESULT_TEMPORARILY_REJECTED, "")
        return

    def job(ap: AutopilotLike) -> None:
        try:
            result, text = fn(ap)
        except AirSitlError as err:
            result, text = mav.MAV_RESULT_DENIED, str(err)
        except Exception as err:  # a bug in the autopilot: keep the vehicle serving
            traceback.print_exc(file=sys.stderr)
            result, text = mav.MAV_RESULT_FAILED, f"{type(err).__name__}: {err}"
        ep.to_io(lambda: ack(result, text))

    ep.post(job)


class Commands(EndpointPart):
    """Handlers of the commands and control messages of one endpoint."""

    def handlers(self) -> dict[str, Handler]:
        return {
            "COMMAND_LONG": self.on_command,
            "COMMAND_INT": self.on_command,
            "SET_MODE": self.on_set_mode,
            "MISSION_SET_CURRENT": self.on_mission_set_current,
            "TIMESYNC": self.on_timesync,
            "REQUEST_DATA_STREAM": self.on_request_data_stream,
        }

    def ack(self, ch: Channel, msg: Message, result: int, text: str = "") -> None:
        """COMMAND_ACK to the sender of ``msg`` (and ``text`` as STATUSTEXT to everyone)."""
        if text:
            sev = SEVERITY_INFO if result == mav.MAV_RESULT_ACCEPTED else SEVERITY_CRITICAL
            self._ep.broadcast_text(sev, text)
        ack = mav.MAVLink_command_ack_message(
            msg.command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        )
        self._ep.reply(ch, ack)

    def on_sim(self, ch: Channel, msg: Message, fn: SimCommand) -> None:
        """Run an autopilot command on the simulation thread, then ACK it from here."""
        run_then_ack(self._ep, fn, lambda result, text: self.ack(ch, msg, result, text))

    def on_command(self, ch: Channel, msg: Message) -> None:
        """Every COMMAND_LONG/INT gets a COMMAND_ACK, even when handling it fails."""
        try:
            self._command(ch, msg)
        except Exception as err:
            traceback.print_exc(file=sys.stderr)
            self.ack(ch, msg, mav.MAV_RESULT_FAILED, f"{type(err).__name__}: {err}")

    def _command(self, ch: Channel, msg: Message) -> None:
        ep = self._ep
        cmd = msg.command
        p1, p2, p3, _p4 = msg.param1, msg.param2, msg.param3, msg.param4
        if msg.get_type() == "COMMAND_INT":
            scale = 1e-7 if msg.frame in (0, 3, 5, 6, 10, 11) else 1.0
            p5, p6, p7 = msg.x * scale, msg.y * scale, msg.z
            relative_alt = msg.frame in (3, 6)
        else:
            p5, p6, p7 = msg.param5, msg.param6, msg.param7
            relative_alt = False
        home_alt = ep.home.alt_amsl_m
        accepted = mav.MAV_RESULT_ACCEPTED

        def simple(call: Callable[[AutopilotLike], Any], failure: str = "") -> None:
            def fn(ap: AutopilotLike) -> tuple[int, str]:
                ok, reason = outcome(call(ap))
                if ok:
                    return accepted, ""
                return mav.MAV_RESULT_DENIED, (failure + reason) if reason else failure.rstrip(": ")

            self.on_sim(ch, msg, fn)

        if cmd == mav.MAV_CMD_COMPONENT_ARM_DISARM:
            if p1 >= 0.5:
                simple(lambda ap: ap.arm(), "Preflight Fail: ")
            else:
                simple(lambda ap: ap.disarm(), "Disarm denied: ")
        elif cmd == mav.MAV_CMD_DO_SET_MODE:
            mode = tm.PX4_TO_MODE.get((whole(p2), whole(p3)))
            if not (whole(p1) & mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED) or mode is None:
                self.ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
                return
            simple(lambda ap: ap.set_mode(mode), f"Mode {mode.name} denied: ")
        elif cmd == mav.MAV_CMD_MISSION_START:
            simple(lambda ap: ap.start_mission(), "Mission start denied: ")
        elif cmd == mav.MAV_CMD_NAV_TAKEOFF:
            alt = (p7 if relative_alt else p7 - home_alt) if math.isfinite(p7) else math.nan
            simple(lambda ap: ap.takeoff(alt), "Takeoff denied: ")
        elif cmd == mav.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            simple(lambda ap: ap.return_to_launch(), "RTL denied: ")
        elif cmd == mav.MAV_CMD_NAV_LAND:
            # PX4: Land mode, straight ahead of where the aircraft is (MAVSDK's action.land()).
            simple(lambda ap: ap.set_mode(FlightMode.LAND), "Land denied: ")
        elif cmd == mav.MAV_CMD_DO_SET_MISSION_CURRENT:
            self._set_mission_current(ch, msg, whole(p1), p2 >= 0.5, simple)
        elif cmd == mav.MAV_CMD_DO_REPOSITION:
            alt = p7 + home_alt if relative_alt and math.isfinite(p7) else p7
            here = ep.latest
            if here is not None and not (math.isfinite(p5) and math.isfinite(p6)):
                p5, p6 = here.state.lat_deg, here.state.lon_deg  # NaN: loiter where we are
            simple(lambda ap: ap.reposition(p5, p6, alt), "Reposition denied: ")
        elif cmd == mav.MAV_CMD_DO_CHANGE_SPEED:
            if not (math.isfinite(p2) and p2 > 0):
                self.ack(ch, msg, mav.MAV_RESULT_DENIED, f"Bad speed {p2}")
                return
            simple(lambda ap: ap.change_speed(p2), "Speed change denied: ")
        elif cmd == mav.MAV_CMD_IMAGE_START_CAPTURE:
            simple(lambda ap: ap.start_capture())
        elif cmd == mav.MAV_CMD_IMAGE_STOP_CAPTURE:
            simple(lambda ap: ap.stop_capture())
        elif cmd == mav.MAV_CMD_REQUEST_MESSAGE:
            self.request_message(ch, msg, whole(p1))
        elif cmd == mav.MAV_CMD_SET_MESSAGE_INTERVAL:
            ok = ep.streams.set_interval(ch.link, whole(p1), p2)
            self.ack(ch, msg, mav.MAV_RESULT_ACCEPTED if ok else mav.MAV_RESULT_UNSUPPORTED)
        elif cmd == mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self.request_message(ch, msg, mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        elif cmd == mav.MAV_CMD_GET_HOME_POSITION:
            self.request_message(ch, msg, mav.MAVLINK_MSG_ID_HOME_POSITION)
        else:
            self.ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)

    def _set_mission_current(
        self,
        ch: Channel,
        msg: Message,
        seq: int,
        reset: bool,
        simple: Callable[[Callable[[AutopilotLike], Any]], None],
    ) -> None:
        """MAV_CMD_DO_SET_MISSION_CURRENT: ``seq`` -1 keeps the current item (common.xml); with
        param2 = 1 ("reset mission") the item is entered again and a completed mission resumes.
        """
        ep = self._ep
        total = len(ep.protocol.items(MissionType.MISSION))
        if seq == -1:
            if not reset:
                self.ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
                return
            if total == 0:
                self.ack(ch, msg, mav.MAV_RESULT_DENIED, "No mission")
                return
            latest = ep.latest
            here = latest.autopilot.current_seq if latest is not None else 0
            seq = min(max(here, 0), total - 1)
        if not 0 <= seq < total:
            self.ack(ch, msg, mav.MAV_RESULT_DENIED, f"No mission item {seq}")
            return
        simple(lambda ap: ap.set_current(seq))

    def request_message(self, ch: Channel, msg: Message, msg_id: int) -> None:
        """ACK then send the message asked for, or UNSUPPORTED."""
        ep = self._ep
        reply = ep.streams.build(msg_id, ep.latest, ep.sink.last_fix)
        if reply is None:
            self.ack(ch, msg, mav.MAV_RESULT_UNSUPPORTED)
            return
        self.ack(ch, msg, mav.MAV_RESULT_ACCEPTED)
        ep.reply(ch, reply)

    def on_set_mode(self, ch: Channel, msg: Message) -> None:
        """SET_MODE with a PX4 custom mode."""
        main, sub = (msg.custom_mode >> 16) & 0xFF, (msg.custom_mode >> 24) & 0xFF
        mode = tm.PX4_TO_MODE.get((main, sub))
        if mode is not None:
            self._ep.on_sim(lambda ap: ap.set_mode(mode))

    def on_mission_set_current(self, ch: Channel, msg: Message) -> None:
        """MISSION_SET_CURRENT (deprecated for MAV_CMD_DO_SET_MISSION_CURRENT)."""
        ep = self._ep
        seq = msg.seq
        total = len(ep.protocol.items(MissionType.MISSION))
        if not 0 <= seq < total:
            ep.reply(ch, tm.mission_current(ep.latest, total))
            return

        def job(ap: AutopilotLike) -> None:
            ap.set_current(seq)

        ep.on_sim(job)

    def on_request_data_stream(self, ch: Channel, msg: Message) -> None:
        """REQUEST_DATA_STREAM (MAVProxy sends it): stream groups on this link, as ArduPilot."""
        self._ep.streams.request_data_stream(
            ch.link, msg.req_stream_id, msg.req_message_rate, bool(msg.start_stop)
        )

    def on_timesync(self, ch: Channel, msg: Message) -> None:
        """TIMESYNC request: answer with our clock."""
        if msg.tc1 == 0:
            self._ep.reply(ch, mav.MAVLink_timesync_message(time.monotonic_ns(), msg.ts1))
