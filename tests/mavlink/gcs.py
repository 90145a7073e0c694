"""A plain pymavlink ground station and a ``serve`` process launcher for the endpoint tests.

Tests synchronise on events (a message, an ACK, a mission state) or on simulated time (the
``time_boot_ms`` of received telemetry), never on wall-clock sleeps. ``SAFETY_S`` bounds every
wait only so that a broken vehicle fails the test instead of hanging it: a busy machine must
never reach it.
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import IO, Any

from ports import free_port
from pymavlink import mavutil

from air_sitl.mavlink.codec import from_mission_message, to_mission_message
from air_sitl.mavlink.messages import MissionItemMessage
from air_sitl.mission.items import MissionItem

PX4_MISSION = (1, 4, 4)  # DO_SET_MODE params QGroundControl sends for "Mission"
# Wall seconds: only a vehicle that stopped answering gets there.
SAFETY_S = float(os.environ.get("AIR_SITL_TEST_SAFETY_S", "300"))


def free_udp_port() -> int:
    """A UDP port nobody uses right now on 127.0.0.1 (this worker's range)."""
    return free_port(socket.SOCK_DGRAM)


@dataclass
class Served:
    """A running ``air-sitl serve`` process and the local addresses of its links."""

    proc: subprocess.Popen[str]
    ports: list[int]
    banner: str

    def stop(self) -> tuple[int, str]:
        """SIGTERM, then the exit code and the rest of stdout."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            out, _ = self.proc.communicate(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            out, _ = self.proc.communicate()
        return self.proc.returncode, out


@contextlib.contextmanager
def serve(
    *args: str, timeout_s: float = SAFETY_S, stderr: IO[str] | None = None
) -> Iterator[Served]:
    """Start ``air-sitl serve ARGS``, wait for its banner, stop it at the end."""
    # No video unless asked for: the tests never send to QGroundControl's port 5600.
    video = () if any(a.startswith(("--video", "--no-video")) for a in args) else ("--no-video",)
    cmd = [sys.executable, "-m", "air_sitl", "serve", *args, *video]
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=stderr, text=True, env=env, bufsize=1
    )
    served = None
    try:
        assert proc.stdout is not None
        deadline = time.monotonic() + timeout_s
        banner = ""
        while time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            if "vehicle ready" in line:
                banner = line
                break
        assert banner, f"serve did not start (exit {proc.poll()})"
        ports = [int(p) for p in re.findall(r"\(local [^:]+:(\d+)\)", banner)]
        served = Served(proc, ports, banner)
        yield served
    finally:
        if served is not None:
            served.stop()
        elif proc.poll() is None:
            proc.kill()
            proc.communicate()


class Gcs:
    """A ground station built from pymavlink alone, doing what QGroundControl does by hand."""

    def __init__(self, url: str, *, system_id: int = 255, component_id: int = 190) -> None:
        self.conn: Any = mavutil.mavlink_connection(
            url, source_system=system_id, source_component=component_id, dialect="common"
        )
        self.texts: list[str] = []
        self.statustexts: list[Any] = []  # the messages, with their chunk id and chunk_seq
        self.sim_ms = 0  # the latest time_boot_ms the vehicle sent

    def close(self) -> None:
        """Close the socket."""
        self.conn.close()

    def recv(self, types: Sequence[str], timeout_s: float = SAFETY_S) -> Any:
        """The next message of one of ``types`` (STATUSTEXTs seen on the way are kept)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            self._note(msg)
            if msg.get_type() in types:
                return msg
        return None

    def _note(self, msg: Any) -> None:
        kind = msg.get_type()
        if kind == "STATUSTEXT":
            self.texts.append(msg.text)
            self.statustexts.append(msg)
        if msg.get_srcSystem() == 1 and hasattr(msg, "time_boot_ms"):
            self.sim_ms = max(self.sim_ms, int(msg.time_boot_ms))

    def drain(self) -> None:
        """Read what already waits in the socket (a backlog from before a change)."""
        while (msg := self.conn.recv_match(blocking=False)) is not None:
            self._note(msg)

    def collect(self, types: Sequence[str], sim_s: float) -> list[Any]:
        """Every message of ``types`` while ``sim_s`` simulated seconds pass (by time_boot_ms)."""
        out: list[Any] = []
        deadline = time.monotonic() + SAFETY_S
        start = -1
        while time.monotonic() < deadline:
            msg = self.conn.recv_match(blocking=True, timeout=0.05)
            if msg is None:
                continue
            self._note(msg)
            if start < 0 and self.sim_ms > 0:
                start = self.sim_ms
            if msg.get_type() in types:
                out.append(msg)
            if start >= 0 and self.sim_ms >= start + sim_s * 1000:
                return out
        raise AssertionError(f"simulated time stopped at {self.sim_ms} ms")

    def wait_text(self, fragment: str) -> str:
        """The first STATUSTEXT (seen before or now) containing ``fragment``."""
        deadline = time.monotonic() + SAFETY_S
        while time.monotonic() < deadline:
            for text in self.texts:
                if fragment in text:
                    return text
            self.recv(["STATUSTEXT"], 1.0)
        raise AssertionError(f"no STATUSTEXT with {fragment!r}: {self.texts}")

    def wait_whole_text(self, fragment: str) -> str:
        """The whole text of the first STATUSTEXT whose first chunk contains ``fragment``: a
        text over 50 characters comes as MAVLink 2 chunks sharing a non-zero id, joined here."""
        self.wait_text(fragment)
        first = next(m for m in self.statustexts if fragment in m.text)
        if first.id == 0:
            return str(first.text)
        chunks = [m for m in self.statustexts if m.id == first.id]
        while len(chunks[-1].text) == 50:
            msg = self.recv(["STATUSTEXT"])
            assert msg is not None, "the rest of a chunked STATUSTEXT did not come"
            if msg.id == first.id:
                chunks.append(msg)
        return "".join(m.text for m in chunks)

    def connect(self, timeout_s: float = SAFETY_S) -> Any:
        """Send heartbeats until the vehicle's heartbeat arrives."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            self.conn.mav.heartbeat_send(
                mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0
            )
            hb = self.recv(["HEARTBEAT"], timeout_s=0.5)
            if hb is not None and hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1:
                self.conn.target_system, self.conn.target_component = 1, 1
                return hb
        raise AssertionError("no heartbeat from the vehicle")

    def upload(
        self, items: Sequence[MissionItem], mission_type: int = 0, current: int | None = 0
    ) -> int:
        """Upload by MISSION_COUNT / MISSION_REQUEST_INT / MISSION_ITEM_INT; the ACK result.
        ``current``: the item flagged current (None: none flagged).

        As QGroundControl does, answers of another list's exchange are not this one's, and an
        ACCEPTED before the last item went out is a late duplicate of an earlier exchange (a
        busy vehicle re-asks an item whose answer is on its way, then acknowledges twice)."""
        self.conn.mav.mission_count_send(1, 1, len(items), mission_type)
        sent_last = not items
        while True:
            msg = self.recv(["MISSION_REQUEST_INT", "MISSION_REQUEST", "MISSION_ACK"])
            assert msg is not None, "upload: the vehicle stopped answering"
            if getattr(msg, "mission_type", 0) != mission_type:
                continue
            if msg.get_type() == "MISSION_ACK":
                if msg.type == mavutil.mavlink.MAV_MISSION_ACCEPTED and not sent_last:
                    continue
                return int(msg.type)
            sent_last = sent_last or msg.seq == len(items) - 1
            item = MissionItemMessage(
                seq=msg.seq,
                item=items[msg.seq],
                mission_type=mission_type,
                current=msg.seq == current,
            )
            self.conn.mav.send(from_mission_message(item, 1, 1))

    def download(self, mission_type: int = 0) -> list[MissionItem]:
        """Download with MISSION_REQUEST_LIST / MISSION_REQUEST_INT."""
        self.conn.mav.mission_request_list_send(1, 1, mission_type)
        count = self.recv(["MISSION_COUNT"])
        while count is not None and getattr(count, "mission_type", 0) != mission_type:
            count = self.recv(["MISSION_COUNT"])  # another list's (a late duplicate)
        assert count is not None, "download: no MISSION_COUNT"
        items: list[MissionItem] = []
        for seq in range(count.count):
            deadline = time.monotonic() + SAFETY_S
            msg = None
            while msg is None and time.monotonic() < deadline:
                # Re-asked as a GCS does (the protocol's retry), should a datagram be lost.
                self.conn.mav.mission_request_int_send(1, 1, seq, mission_type)
                msg = self.recv(["MISSION_ITEM_INT"], 2.0)
                if msg is not None and (msg.seq != seq or msg.mission_type != mission_type):
                    msg = None
            assert msg is not None, f"download: no item {seq}"
            converted = to_mission_message(msg)
            assert isinstance(converted, MissionItemMessage)
            items.append(converted.item)
        self.conn.mav.mission_ack_send(1, 1, 0, mission_type)
        return items

    def command(
        self, command: int, *params: float, timeout_s: float = SAFETY_S, component: int = 1
    ) -> int:
        """COMMAND_LONG, the result of its COMMAND_ACK (re-sent, as GCSs do, while unanswered)."""
        p = [*params, *([0.0] * (7 - len(params)))]
        deadline = time.monotonic() + timeout_s
        confirmation = 0
        while time.monotonic() < deadline:
            self.conn.mav.command_long_send(1, component, command, confirmation, *p)
            confirmation = min(confirmation + 1, 255)
            resend = time.monotonic() + 2.0
            while time.monotonic() < min(resend, deadline):
                ack = self.recv(["COMMAND_ACK"], timeout_s=resend - time.monotonic())
                if ack is not None and ack.command == command:
                    assert ack.get_srcComponent() == component, "answered by another component"
                    return int(ack.result)
        raise AssertionError(f"no COMMAND_ACK for command {command}")

    def params(self) -> dict[str, float]:
        """PARAM_REQUEST_LIST: every parameter by name."""
        self.conn.mav.param_request_list_send(1, 1)
        values: dict[str, float] = {}
        total = math.inf
        while len(values) < total:
            msg = self.recv(["PARAM_VALUE"])
            assert msg is not None, f"param list stopped after {len(values)}"
            total = msg.param_count
            values[msg.param_id] = msg.param_value
        return values

    def set_param(self, name: str, value: float) -> float:
        """PARAM_SET; the value of the PARAM_VALUE that answers it."""
        self.conn.mav.param_set_send(
            1, 1, name.encode("ascii"), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32
        )
        deadline = time.monotonic() + SAFETY_S
        while time.monotonic() < deadline:
            msg = self.recv(["PARAM_VALUE"], 1.0)
            if msg is not None and msg.param_id == name:
                return float(msg.param_value)
        raise AssertionError(f"no PARAM_VALUE for {name}")
