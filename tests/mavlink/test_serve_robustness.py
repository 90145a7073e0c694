"""Robustness of the endpoint: garbage on the link, clients that never read, signing."""

from __future__ import annotations

import selectors
import socket
import struct
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from gcs import SAFETY_S, Gcs, serve
from inproc import running_vehicle
from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2

from air_sitl.mavlink.codec import Encoder
from air_sitl.mavlink.links import TCP_MAX_BUFFER_BYTES, TcpServerLink, parse_link
from air_sitl.mission.plan_file import load_mission
from air_sitl.state import GeoPoint

REPO = Path(__file__).resolve().parents[2]
UC200 = REPO / "missions" / "UC-200.plan"
M = mavutil.mavlink
KEY_HEX = "42" * 32
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)


def fuzz_frames(count: int, seed: int) -> list[bytes]:
    """Random and mutated frames: bad CRC, truncated, unknown ids, len 0/255, bad flags, v1/v2."""
    rng = np.random.default_rng(seed)
    v2 = mavlink2.MAVLink(None, 77, 1)
    v1 = mavlink2.MAVLink(None, 78, 1)
    templates = [
        mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3),
        mavlink2.MAVLink_param_request_read_message(1, 1, b"NO_SUCH_PARAM", -1),
        mavlink2.MAVLink_gps_raw_int_message(1, 3, 2, 3, 4, 5, 6, 7, 8, 9),
        mavlink2.MAVLink_statustext_message(6, b"fuzz", 0, 0),
    ]
    frames: list[bytes] = []
    while len(frames) < count:
        kind = int(rng.integers(0, 8))
        msg = templates[int(rng.integers(0, len(templates)))]
        good = bytearray(msg.pack(v2))
        if kind == 0:  # random bytes, sometimes starting with a magic byte
            data = bytearray(rng.integers(0, 256, int(rng.integers(0, 300)), dtype=np.uint8))
            if data and rng.random() < 0.5:
                data[0] = 0xFD if rng.random() < 0.5 else 0xFE
            frames.append(bytes(data))
        elif kind == 1:  # bad CRC
            good[-1] ^= 0xFF
            frames.append(bytes(good))
        elif kind == 2:  # truncated
            frames.append(bytes(good[: int(rng.integers(1, len(good)))]))
        elif kind == 3:  # unknown message id
            good[7:10] = bytes(rng.integers(0, 256, 3, dtype=np.uint8)) + b""
            good[9] = 0x7F
            frames.append(bytes(good))
        elif kind == 4:  # length 0 or 255
            good[1] = 0 if rng.random() < 0.5 else 255
            frames.append(bytes(good))
        elif kind == 5:  # an incompatibility flag nobody knows
            good[2] = int(rng.integers(2, 256))
            frames.append(bytes(good))
        elif kind == 6:  # MAVLink 1, mutated half of the time
            one = bytearray(msg.pack(v1, force_mavlink1=True))
            if rng.random() < 0.5:
                one[int(rng.integers(1, len(one)))] ^= 0x21
            frames.append(bytes(one))
        else:  # a random payload byte flipped
            good[int(rng.integers(10, len(good)))] ^= int(rng.integers(1, 256))
            frames.append(bytes(good))
    return frames


class HeartbeatWatch(threading.Thread):
    """Counts the vehicle's heartbeats and SYS_STATUS on a separate socket."""

    def __init__(self, port: int) -> None:
        super().__init__(daemon=True)
        self.gcs = Gcs(f"udpout:127.0.0.1:{port}", system_id=250)
        self.gcs.connect()
        self.beats: list[float] = []
        self.errors_comm = 0
        self.stop = threading.Event()

    def run(self) -> None:
        while not self.stop.is_set():
            msg = self.gcs.conn.recv_match(blocking=True, timeout=0.1)
            if msg is None:
                continue
            if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1:
                self.beats.append(time.monotonic())
            elif msg.get_type() == "SYS_STATUS":
                self.errors_comm = msg.errors_comm


@pytest.mark.integration
def test_100k_bad_frames_then_a_normal_upload(tmp_path: Path) -> None:
    frames = fuzz_frames(100_000, seed=5)
    err_path = tmp_path / "stderr.txt"
    with err_path.open("w") as err, serve("--mavlink", "udpin:127.0.0.1:0", stderr=err) as s:
        port = s.ports[0]
        watch = HeartbeatWatch(port)
        watch.start()
        fuzzer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        t0 = time.monotonic()
        # Several frames per datagram, paced so most of them reach the parser.
        i = 0
        while i < len(frames):
            n = 1 + i % 4
            fuzzer.sendto(b"".join(frames[i : i + n]), ("127.0.0.1", port))
            i += n
            if i % 2000 < n:
                time.sleep(0.02)
        fuzz_s = time.monotonic() - t0
        gcs = Gcs(f"udpout:127.0.0.1:{port}")
        gcs.connect()
        items = load_mission(UC200).items
        # A random frame may have begun an upload: it is denied until that one times out.
        deadline = time.monotonic() + SAFETY_S
        while (result := gcs.upload(items)) == M.MAV_MISSION_DENIED:
            assert time.monotonic() < deadline
            gcs.recv(["HEARTBEAT"])
        assert result == M.MAV_MISSION_ACCEPTED
        assert len(gcs.download()) == len(items)
        watch.stop.set()
        watch.join()
        # Heartbeats kept coming through the fuzz (1 Hz of wall time: a generous bound on the
        # gaps, which only a stalled endpoint reaches).
        during = [t for t in watch.beats if t0 <= t <= t0 + fuzz_s]
        assert len(during) >= 1 or fuzz_s < 2.0, (len(during), fuzz_s)
        assert np.diff([t0, *during, t0 + fuzz_s]).max() < 10.0
        assert watch.errors_comm > 10_000  # parse errors counted (SYS_STATUS.errors_comm)
        assert s.proc.poll() is None
        code, out = s.stop()
    assert code == 0
    assert "Traceback" not in err_path.read_text()
    counts = out.splitlines()[-1]
    assert "parse errors" in counts


@pytest.mark.integration
def test_a_tcp_client_that_never_reads_does_not_stall_the_simulation() -> None:
    links = ["tcpin:127.0.0.1:0", "udpin:127.0.0.1:0"]
    with running_vehicle(links, HOME, speed=50.0) as vehicle:
        tcp, udp = vehicle.endpoint.links
        stuck = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        stuck.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        stuck.connect(tcp.local_address)
        reader = Gcs(f"tcp:127.0.0.1:{tcp.local_address[1]}", system_id=251)  # a second client
        assert reader.connect().get_srcSystem() == 1
        gcs = Gcs(f"udpout:127.0.0.1:{udp.local_address[1]}")
        gcs.connect()
        # Wait until the endpoint drops frames for the client that reads nothing ...
        dropping = False
        while not dropping:
            gcs.collect(["ATTITUDE"], 1.0)
            dropping = any(ch.dropped_frames > 0 for ch in list(tcp.channels.values()))
        # ... then the simulation goes on: 30 more simulated seconds arrive on the UDP link,
        # with ATTITUDE at 1 kHz there.
        assert gcs.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, 30, 1000) == M.MAV_RESULT_ACCEPTED
        att = gcs.collect(["ATTITUDE"], 30.0)
        assert (att[-1].time_boot_ms - att[0].time_boot_ms) / 1000 > 29.0
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == M.MAV_RESULT_ACCEPTED
        reader.drain()
        assert reader.recv(["HEARTBEAT"]) is not None
        stuck.close()
        reader.close()
        gcs.close()


def test_tcp_link_send_never_blocks_and_drops_for_a_full_client() -> None:
    link = TcpServerLink(parse_link("tcpin:127.0.0.1:0"), Encoder(1, 1), lambda *a: None, object)
    sel = selectors.DefaultSelector()
    link.register(sel)
    client = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    client.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    client.connect(link.local_address)
    for key, mask in sel.select(1.0):
        link.on_ready(sel, key, mask)
    (ch,) = link.channels.values()
    frame = b"\xfd" + bytes(279)
    for _ in range(20_000):  # 5.6 MB to a client that reads nothing: returns, never blocks
        link.send(frame)
    assert ch.dropped_frames > 0
    assert len(ch.outbuf) <= TCP_MAX_BUFFER_BYTES
    client.close()
    link.close()
    sel.close()


@pytest.mark.integration
def test_signing_rejects_unsigned_and_accepts_signed() -> None:
    # At 4x: the two simulated seconds read below are a margin in simulated time.
    with serve("--mavlink", "udpin:127.0.0.1:0", "--signing-key", KEY_HEX, "--speed", "4") as s:
        port = s.ports[0]
        unsigned = Gcs(f"udpout:127.0.0.1:{port}", system_id=201)
        hb = unsigned.connect()  # telemetry is sent signed; unsigned readers still parse it
        assert hb.get_header().incompat_flags & 0x01
        unsigned.conn.mav.command_long_send(
            1, 1, M.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0
        )
        signed = Gcs(f"udpout:127.0.0.1:{port}", system_id=202)
        signed.conn.setup_signing(bytes.fromhex(KEY_HEX), sign_outgoing=True)
        signed.connect()
        assert signed.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == M.MAV_RESULT_ACCEPTED
        # The signed command was answered after the unsigned one arrived: no ACK came for the
        # unsigned one meanwhile. The unsigned client reads on until two simulated seconds of
        # telemetry sent after the answer have reached it (the signed client may have had its
        # ACK before any time-stamped message: the time is read on the unsigned side).
        unsigned.drain()
        heard = unsigned.collect(["COMMAND_ACK", "ATTITUDE"], 2.0)
        assert [m for m in heard if m.get_type() == "ATTITUDE"]
        assert not [m for m in heard if m.get_type() == "COMMAND_ACK"]
        status = signed.recv(["SYS_STATUS"])
        assert status.errors_comm >= 2  # the unsigned heartbeats and command were dropped
        unsigned.close()
        signed.close()
        code, out = s.stop()
    assert code == 0
    assert "signature rejected" in out and " 0 signature rejected" not in out


def test_fuzz_frames_are_deterministic() -> None:
    assert fuzz_frames(500, seed=1) == fuzz_frames(500, seed=1)
    assert len({struct.pack("<I", len(f)) for f in fuzz_frames(500, seed=2)}) > 50
