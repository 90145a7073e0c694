"""MAVLink FTP: every request answered at once (the vehicle has no files), so MAVProxy's
``@PARAM/param.pck`` fetch fails fast and it falls back to PARAM_REQUEST_LIST."""

from __future__ import annotations

import struct

import pytest
from gcs import SAFETY_S, Gcs
from inproc import running_vehicle
from pymavlink.mavftp import MAVFTP, FtpError

from air_sitl.mavlink import ftp
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)


def request(seq: int, opcode: int, data: bytes = b"", session: int = 0) -> bytes:
    header = struct.pack("<HBBBBBBI", seq, session, opcode, len(data), 0, 0, 0, 0)
    return header + data


@pytest.mark.parametrize(
    ("opcode", "error"),
    [
        (ftp.OP_OPEN_FILE_RO, ftp.ERR_FILE_NOT_FOUND),
        (ftp.OP_LIST_DIRECTORY, ftp.ERR_FILE_NOT_FOUND),
        (ftp.OP_CALC_FILE_CRC32, ftp.ERR_FILE_NOT_FOUND),
        (ftp.OP_BURST_READ_FILE, ftp.ERR_INVALID_SESSION),
        (ftp.OP_READ_FILE, ftp.ERR_INVALID_SESSION),
        (ftp.OP_CREATE_FILE, ftp.ERR_FILE_PROTECTED),
        (ftp.OP_REMOVE_FILE, ftp.ERR_FILE_PROTECTED),
        (99, ftp.ERR_UNKNOWN_COMMAND),
    ],
)
def test_naks_carry_the_error_and_echo_the_request(opcode: int, error: int) -> None:
    reply = ftp.answer(request(41, opcode, b"@PARAM/param.pck", session=3))
    assert reply is not None and len(reply) == ftp.PAYLOAD_BYTES
    seq, session, op, size, req_opcode = struct.unpack_from("<HBBBB", reply)
    assert (seq, session, op, size, req_opcode) == (42, 3, ftp.OP_NAK, 1, opcode)
    assert reply[12] == error


def test_the_root_lists_empty() -> None:
    reply = ftp.answer(request(7, ftp.OP_LIST_DIRECTORY, b"/"))
    assert reply is not None and reply[3] == ftp.OP_NAK and reply[12] == ftp.ERR_EOF


def test_session_resets_are_acked_and_replies_ignored() -> None:
    for opcode in (ftp.OP_TERMINATE_SESSION, ftp.OP_RESET_SESSIONS):
        reply = ftp.answer(request(65535, opcode))
        assert reply is not None
        assert struct.unpack_from("<HBBBB", reply) == (0, 0, ftp.OP_ACK, 0, opcode)
    assert ftp.answer(request(1, ftp.OP_ACK)) is None
    assert ftp.answer(request(1, ftp.OP_NAK)) is None
    assert ftp.answer(b"\x01") is None


@pytest.mark.integration
def test_mavproxys_param_fetch_is_refused_by_pymavlinks_mavftp() -> None:
    """pymavlink.mavftp is MAVProxy's FTP client: it gets FileNotFound, not a timeout."""
    with running_vehicle(["udpin:127.0.0.1:0"], HOME, speed=1.0) as vehicle:
        gcs = Gcs(f"udpout:127.0.0.1:{vehicle.endpoint.links[0].local_address[1]}")
        gcs.connect()
        client = MAVFTP(gcs.conn, 1, 1)
        client.cmd_get(["@PARAM/param.pck?withdefaults=1"], callback=lambda _fh: None)
        result = client.process_ftp_reply("OpenFileRO", timeout=SAFETY_S)
        assert result.error_code == FtpError.FileNotFound
        gcs.close()
