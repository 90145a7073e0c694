"""A burst of PARAM_SET on a UDP link: the socket's buffer is sized for bursts, and every
datagram is accounted for in serve's exit line, received or dropped by the kernel (Linux)."""

from __future__ import annotations

import re
import subprocess
import sys

import pytest
from gcs import Gcs, serve
from pymavlink import mavutil

from air_sitl.mavlink.links import UDP_RCVBUF_BYTES

pytestmark = pytest.mark.integration

M = mavutil.mavlink
EXIT_LINE = re.compile(
    r"stopped; (\d+) messages received, .*, (\d+) datagrams dropped by the kernel"
)


def receive_buffer_bytes(port: int) -> int | None:
    """The kernel's receive buffer of the UDP socket bound to ``port`` (``ss``), or None."""
    try:
        done = subprocess.run(
            ["ss", "-uanmH", "sport", "=", f":{port}"], capture_output=True, text=True, check=True
        )
    except (OSError, subprocess.CalledProcessError):
        return None
    found = re.search(r"rb(\d+)", done.stdout)
    return int(found.group(1)) if found else None


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="drop counts are Linux's")
@pytest.mark.parametrize("burst", [5_000, 30_000])
def test_a_param_set_burst_is_received_or_counted(burst: int) -> None:
    with serve("--mavlink", "udpin:127.0.0.1:0") as s:
        port = s.ports[0]
        rb = receive_buffer_bytes(port)
        if rb is not None:
            with open("/proc/sys/net/core/rmem_max") as f:
                cap = int(f.read())
            assert rb >= min(UDP_RCVBUF_BYTES, cap), rb  # sized, as far as the kernel allows
        gcs = Gcs(f"udpout:127.0.0.1:{port}")
        sent = 0
        try:
            deadline_beats = 0
            while gcs.recv(["HEARTBEAT"], timeout_s=0.2) is None and deadline_beats < 1000:
                gcs.conn.mav.heartbeat_send(M.MAV_TYPE_GCS, M.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                sent += 1
                deadline_beats += 1
            for i in range(burst):
                gcs.conn.mav.param_set_send(
                    1, 1, b"FW_AIRSPD_TRIM", 15.0 + (i % 10) * 0.1, M.MAV_PARAM_TYPE_REAL32
                )
            sent += burst
            # Drained: a request sent after the burst is answered (resent while it is lost).
            answered = False
            while not answered:
                gcs.conn.mav.param_request_read_send(1, 1, b"FW_AIRSPD_MAX", -1)
                sent += 1
                reply = gcs.recv(["PARAM_VALUE"], timeout_s=0.5)
                while reply is not None and reply.param_id != "FW_AIRSPD_MAX":
                    reply = gcs.recv(["PARAM_VALUE"], timeout_s=0.5)
                answered = reply is not None
        finally:
            gcs.close()
        code, out = s.stop()
    assert code == 0
    found = EXIT_LINE.search(out)
    assert found is not None, out
    received, dropped = int(found.group(1)), int(found.group(2))
    assert received + dropped == sent, (received, dropped, sent)
