"""MAVLink FTP (FILE_TRANSFER_PROTOCOL) answered at once: the vehicle has no file system.

MAVProxy first asks for ``@PARAM/param.pck`` and waits for an answer before it falls back to
PARAM_REQUEST_LIST; QGroundControl asks for component metadata files. Every request gets its
reply straight away, as mavlink.io's "File Transfer Protocol" defines it: a NAK with
FileNotFound for a path (there are none; the root lists empty: a NAK with EOF), InvalidSession
for a read without an open file, FileProtected for anything that writes, UnknownCommand for
an opcode we do not know; ACK for TerminateSession and ResetSessions. The reply's
``seq_number`` is the request's plus one and its ``req_opcode`` the request's opcode.
"""

from __future__ import annotations

import struct

from air_sitl.mavlink.codec import Message, mav
from air_sitl.mavlink.interfaces import EndpointPart, Handler
from air_sitl.mavlink.links import Channel

# Header: seq_number u16, session u8, opcode u8, size u8, req_opcode u8, burst_complete u8,
# padding u8, offset u32; then up to 239 bytes of data.
_HEADER = struct.Struct("<HBBBBBBI")
PAYLOAD_BYTES = 251

OP_NONE, OP_TERMINATE_SESSION, OP_RESET_SESSIONS, OP_LIST_DIRECTORY = 0, 1, 2, 3
OP_OPEN_FILE_RO, OP_READ_FILE, OP_CREATE_FILE, OP_WRITE_FILE, OP_REMOVE_FILE = 4, 5, 6, 7, 8
OP_CREATE_DIRECTORY, OP_REMOVE_DIRECTORY, OP_OPEN_FILE_WO, OP_TRUNCATE_FILE = 9, 10, 11, 12
OP_RENAME, OP_CALC_FILE_CRC32, OP_BURST_READ_FILE = 13, 14, 15
OP_ACK, OP_NAK = 128, 129

ERR_FAIL, ERR_INVALID_SESSION, ERR_EOF, ERR_UNKNOWN_COMMAND = 1, 4, 6, 7
ERR_FILE_PROTECTED, ERR_FILE_NOT_FOUND = 9, 10

_BY_PATH = {OP_LIST_DIRECTORY, OP_OPEN_FILE_RO, OP_CALC_FILE_CRC32}
_BY_SESSION = {OP_READ_FILE, OP_BURST_READ_FILE, OP_WRITE_FILE}
_WRITES = {
    OP_CREATE_FILE, OP_REMOVE_FILE, OP_CREATE_DIRECTORY, OP_REMOVE_DIRECTORY,
    OP_OPEN_FILE_WO, OP_TRUNCATE_FILE, OP_RENAME,
}  # fmt: skip


def answer(request: bytes) -> bytes | None:
    """The reply payload to one request payload; None for what is itself a reply."""
    if len(request) < _HEADER.size:
        return None
    seq, session, opcode, size, _req, _burst, _pad, offset = _HEADER.unpack_from(request)
    if opcode in (OP_ACK, OP_NAK):
        return None
    if opcode in (OP_TERMINATE_SESSION, OP_RESET_SESSIONS):
        return _reply(seq, session, OP_ACK, opcode, offset, b"")
    path = request[_HEADER.size : _HEADER.size + size].rstrip(b"\0")
    if opcode == OP_LIST_DIRECTORY and path in (b"", b"/", b"."):
        error = ERR_EOF  # the root exists and is empty
    elif opcode in _BY_PATH:
        error = ERR_FILE_NOT_FOUND
    elif opcode in _BY_SESSION:
        error = ERR_INVALID_SESSION
    elif opcode in _WRITES:
        error = ERR_FILE_PROTECTED
    else:
        error = ERR_UNKNOWN_COMMAND
    return _reply(seq, session, OP_NAK, opcode, offset, bytes([error]))


def _reply(seq: int, session: int, opcode: int, req_opcode: int, offset: int, data: bytes) -> bytes:
    header = _HEADER.pack((seq + 1) & 0xFFFF, session, opcode, len(data), req_opcode, 0, 0, offset)
    return (header + data).ljust(PAYLOAD_BYTES, b"\0")


class Ftp(EndpointPart):
    """FILE_TRANSFER_PROTOCOL handler of an endpoint."""

    def handlers(self) -> dict[str, Handler]:
        return {"FILE_TRANSFER_PROTOCOL": self.on_ftp}

    def on_ftp(self, ch: Channel, msg: Message) -> None:
        """Answer the request to its sender at once."""
        reply = answer(bytes(msg.payload))
        if reply is None:
            return
        out = mav.MAVLink_file_transfer_protocol_message(
            0, msg.get_srcSystem(), msg.get_srcComponent(), list(reply)
        )
        self._ep.reply(ch, out)
