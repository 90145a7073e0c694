"""Telemetry message contents (pure: no sockets)."""

from __future__ import annotations

import pytest

from air_sitl.mavlink.telemetry import MISSION_STATE_NO_MISSION, mission_current, statustext


def _text(msg: object) -> str:
    raw = msg.text  # type: ignore[attr-defined]
    return raw.decode() if isinstance(raw, bytes) else str(raw)


@pytest.mark.parametrize("length", [1, 49, 50, 51, 100, 101, 240])
def test_statustext_chunks_follow_common_xml(length: int) -> None:
    text = "".join(chr(ord("a") + i % 26) for i in range(length))
    msgs = statustext(4, text, text_id=7)
    if length <= 50:
        assert len(msgs) == 1 and msgs[0].id == 0 and msgs[0].chunk_seq == 0
    else:
        assert {m.id for m in msgs} == {7}
        assert [m.chunk_seq for m in msgs] == list(range(len(msgs)))
        # The receiver ends on a chunk shorter than 50: an exact multiple ends with an empty one.
        assert len(_text(msgs[-1])) < 50
    assert "".join(_text(m) for m in msgs) == text
    assert {m.severity for m in msgs} == {4}


def test_statustext_chunks_need_an_id() -> None:
    with pytest.raises(ValueError, match="id"):
        statustext(4, "x" * 60, text_id=0)


def test_mission_current_without_a_mission_says_so_as_common_xml() -> None:
    msg = mission_current(None, 0)
    assert (msg.total, msg.mission_state) == (65535, MISSION_STATE_NO_MISSION)
    assert mission_current(None, 8).total == 8
