"""A ground station that does what QGroundControl does with cameras and several vehicles:
pymavlink listening on the ground-station port (udpin: it answers every vehicle it heard),
commands addressed to a system and component, camera discovery as QGC's QGCCameraManager."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any

from pymavlink import mavutil

from air_sitl.mavlink.codec import from_mission_message
from air_sitl.mavlink.messages import MissionItemMessage
from air_sitl.mission.items import MissionItem

M = mavutil.mavlink
SAFETY_S = 120.0
CAMERA = M.MAV_COMP_ID_CAMERA


class QgcLike:
    """One MAVLink connection, any number of vehicles (by system id)."""

    def __init__(self, url: str) -> None:
        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=255, source_component=190, dialect="common"
        )
        self.heard: set[tuple[int, int]] = set()  # (system, component) of every heartbeat

    def close(self) -> None:
        self.conn.close()

    def recv(self, types: Sequence[str], system: int | None = None, component: int | None = None,
             timeout_s: float = SAFETY_S) -> Any:  # fmt: skip
        """The next message of ``types`` from ``system``/``component`` (any when None)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            src = (msg.get_srcSystem(), msg.get_srcComponent())
            if msg.get_type() == "HEARTBEAT":
                self.heard.add(src)
            if msg.get_type() not in types:
                continue
            if system is not None and src[0] != system:
                continue
            if component is not None and src[1] != component:
                continue
            return msg
        return None

    def heartbeat(self) -> None:
        """The ground station's own HEARTBEAT (QGC sends one a second)."""
        self.conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def wait_heard(self, wanted: set[tuple[int, int]], timeout_s: float = SAFETY_S) -> None:
        """Heartbeats from every (system, component) in ``wanted``."""
        deadline = time.monotonic() + timeout_s
        while not wanted <= self.heard:
            assert time.monotonic() < deadline, f"heard {sorted(self.heard)}"
            self.heartbeat()
            self.recv(["HEARTBEAT"], timeout_s=0.5)

    def command(self, system: int, component: int, command: int, *params: float) -> int:
        """COMMAND_LONG, re-sent while unanswered; the result of its COMMAND_ACK."""
        p = [*params, *([0.0] * (7 - len(params)))]
        deadline = time.monotonic() + SAFETY_S
        while time.monotonic() < deadline:
            self.conn.mav.command_long_send(system, component, command, 0, *p)
            resend = time.monotonic() + 2.0
            while time.monotonic() < resend:
                ack = self.recv(["COMMAND_ACK"], system, component, resend - time.monotonic())
                if ack is not None and ack.command == command:
                    return int(ack.result)
        raise AssertionError(f"no COMMAND_ACK for {command} from {system}/{component}")

    def request(self, system: int, component: int, command: int, reply: str,
                *params: float) -> Any:  # fmt: skip
        """A request command (MAV_CMD_REQUEST_MESSAGE or a legacy one): ACCEPTED, then the
        message ``reply`` from that component."""
        assert self.command(system, component, command, *params) == M.MAV_RESULT_ACCEPTED
        msg = self.recv([reply], system, component, 10.0)
        assert msg is not None, f"no {reply} after command {command}"
        return msg

    def upload(self, system: int, items: Sequence[MissionItem]) -> int:
        """The mission upload protocol with vehicle ``system``; the MISSION_ACK result."""
        self.conn.mav.mission_count_send(system, 1, len(items), 0)
        while True:
            msg = self.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"], system)
            assert msg is not None, "upload: the vehicle stopped answering"
            if msg.get_type() == "MISSION_ACK":
                return int(msg.type)
            item = MissionItemMessage(seq=msg.seq, item=items[msg.seq], mission_type=0,
                                      current=msg.seq == 0)  # fmt: skip
            self.conn.mav.send(from_mission_message(item, system, 1))
