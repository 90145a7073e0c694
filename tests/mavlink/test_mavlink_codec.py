"""Codec: bytes in never raise, drops are counted, signing accepts and rejects the right frames."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mission_samples import LOITER_TURNS
from pymavlink.dialects.v20 import common as mavlink2

from air_sitl.errors import MavlinkError
from air_sitl.mavlink.codec import (
    Encoder,
    ParseCounters,
    Parser,
    Signing,
    from_mission_message,
    load_signing_key,
    to_mission_message,
)
from air_sitl.mavlink.links import parse_link
from air_sitl.mavlink.messages import MissionItemMessage

KEY = bytes(range(32))


def heartbeat_frame(encoder: Encoder) -> bytes:
    return encoder.encode(mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.binary(max_size=300), max_size=8))
def test_random_bytes_never_raise(chunks: list[bytes]) -> None:
    counters = ParseCounters()
    parser = Parser(counters)
    good = heartbeat_frame(Encoder(255, 190))
    for chunk in chunks:
        parser.feed(chunk, datagram=True)
    # The parser is still usable afterwards.
    assert [m.get_type() for m in parser.feed(good, datagram=True)] == ["HEARTBEAT"]


def test_drops_are_counted_by_kind() -> None:
    counters = ParseCounters()
    parser = Parser(counters)
    good = heartbeat_frame(Encoder(255, 190))
    bad_crc = good[:-1] + bytes([good[-1] ^ 0xFF])
    flags = bytearray(good)
    flags[2] = 0x80  # an incompatibility flag nobody defined
    unknown = bytearray(good)
    unknown[7:10] = (0xEE, 0xEE, 0x00)  # message id 61166
    assert parser.feed(bad_crc, datagram=True) == []
    assert parser.feed(bytes(flags), datagram=True) == []
    assert parser.feed(good[:9], datagram=True) == []  # truncated
    assert parser.feed(b"\x00\x01\x02", datagram=True) == []  # no magic
    assert parser.feed(bytes(unknown), datagram=True) == []
    assert counters.parse_errors == 4
    assert counters.unknown_ids == 1
    v1 = mavlink2.MAVLink(None, 255, 190)
    v1.WIRE_PROTOCOL_VERSION = "1.0"
    frame_v1 = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(v1, force_mavlink1=True)
    assert [m.get_type() for m in parser.feed(frame_v1 + good, datagram=True)] == [
        "HEARTBEAT",
        "HEARTBEAT",
    ]
    assert counters.messages == 2


def test_stream_parser_keeps_partial_frames_but_datagrams_do_not() -> None:
    good = heartbeat_frame(Encoder(255, 190))
    stream = Parser(ParseCounters())
    assert stream.feed(good[:5]) == []
    assert len(stream.feed(good[5:])) == 1
    counters = ParseCounters()
    dgram = Parser(counters)
    assert dgram.feed(good[:5], datagram=True) == []
    assert dgram.feed(good[5:], datagram=True) == []
    assert counters.parse_errors >= 1


def test_signing_accepts_signed_and_rejects_unsigned_v1_bad_and_replayed() -> None:
    vehicle = Signing(KEY)
    counters = ParseCounters()
    parser = Parser(counters, vehicle)
    client = Encoder(255, 190, Signing(KEY))
    signed = heartbeat_frame(client)
    assert len(parser.feed(signed, datagram=True)) == 1
    # The same frame again is a replay.
    assert parser.feed(signed, datagram=True) == []
    assert counters.replayed == 1
    # Unsigned MAVLink 2, MAVLink 1, and a wrong key are all refused.
    assert parser.feed(heartbeat_frame(Encoder(254, 1)), datagram=True) == []
    v1 = mavlink2.MAVLink(None, 254, 1)
    frame_v1 = mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 0, 3).pack(v1, force_mavlink1=True)
    assert parser.feed(frame_v1, datagram=True) == []
    wrong = Encoder(253, 1, Signing(bytes(32)))
    assert parser.feed(heartbeat_frame(wrong), datagram=True) == []
    assert counters.signature_rejected == 4
    # RADIO_STATUS may come unsigned (radios inject it).
    radio = Encoder(51, 68).encode(mavlink2.MAVLink_radio_status_message(1, 2, 3, 4, 5, 6, 7))
    assert [m.get_type() for m in parser.feed(radio, datagram=True)] == ["RADIO_STATUS"]
    # Later signed frames from the client still pass.
    assert len(parser.feed(heartbeat_frame(client), datagram=True)) == 1


def test_signing_key_from_hex_and_file(tmp_path: Path) -> None:
    hexkey = KEY.hex()
    assert load_signing_key(hexkey) == KEY
    f = tmp_path / "key.txt"
    f.write_text(hexkey + "\n")
    assert load_signing_key(f"@{f}") == KEY
    raw = tmp_path / "key.bin"
    raw.write_bytes(KEY)
    assert load_signing_key(f"@{raw}") == KEY
    with pytest.raises(MavlinkError, match="64 hex digits"):
        load_signing_key("abcd")
    with pytest.raises(MavlinkError, match="cannot read"):
        load_signing_key(f"@{tmp_path / 'missing'}")


def test_mission_item_round_trip_int_and_float() -> None:
    item = LOITER_TURNS
    for int_form in (True, False):
        msg = from_mission_message(MissionItemMessage(seq=3, item=item, int_form=int_form), 1, 1)
        frame = Encoder(255, 190).encode(msg)
        (decoded,) = Parser(ParseCounters()).feed(frame, datagram=True)
        back = to_mission_message(decoded)
        assert isinstance(back, MissionItemMessage) and back.int_form is int_form
        assert back.item.command == item.command and back.seq == 3
        tolerance = 1e-7 if int_form else 1e-5  # float32 degrees in the old message
        assert abs(back.item.lat_deg - item.lat_deg) < tolerance
        assert abs(back.item.lon_deg - item.lon_deg) < tolerance


def test_link_urls() -> None:
    spec = parse_link("udpout:127.0.0.1:14550")
    assert (spec.kind, spec.host, spec.port, spec.loopback) == ("udpout", "127.0.0.1", 14550, True)
    assert parse_link("tcpin://0.0.0.0:5760").loopback is False
    assert parse_link("udpin:[::1]:14550").loopback is True
    for bad in ("serial:/dev/ttyS0", "udpin::14550", "udpout:127.0.0.1:0", "tcpin:1.2.3.4:99999"):
        with pytest.raises(MavlinkError, match="--mavlink"):
            parse_link(bad)


def test_encoder_signs_with_current_time() -> None:
    signing = Signing(KEY)
    frame = heartbeat_frame(Encoder(1, 1, signing))
    assert frame[2] & 0x01  # signed flag
    stamp = int.from_bytes(frame[-12:-6], "little")
    now = int((time.time() - 1_420_070_400) * 100_000)
    assert abs(stamp - now) < 100_000 * 60
