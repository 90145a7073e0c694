"""``serve --max-sim-time``: no limit unless given, and any value given (even 14400) applies."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from air_sitl import serving
from air_sitl.cli import build_parser
from air_sitl.commands import serve
from air_sitl.options import OPEN_END_NS


def _served_limit(monkeypatch: pytest.MonkeyPatch, argv: list[str]) -> int:
    seen: dict[str, Any] = {}

    class _Counters:
        messages = dropped = parse_errors = unknown_ids = signature_rejected = 0

    def fake_serve(setup: object, specs: object, **kw: Any) -> _Counters:
        seen.update(kw)
        return _Counters()

    monkeypatch.setattr(serving, "serve_vehicle", fake_serve)  # serve imports it when it runs
    args = build_parser().parse_args(["serve", "--quiet", "--mavlink", "udpout:127.0.0.1:1", *argv])
    assert serve.run(args) == 0
    return int(seen["max_sim_time_ns"])


def test_serve_runs_until_stopped_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _served_limit(monkeypatch, []) == OPEN_END_NS


@pytest.mark.parametrize("seconds", ["14400", "14400.0", "60"])
def test_an_explicit_limit_applies_even_when_it_equals_the_old_default(
    monkeypatch: pytest.MonkeyPatch, seconds: str
) -> None:
    assert _served_limit(monkeypatch, ["--max-sim-time", seconds]) == int(float(seconds) * 1e9)


def test_serve_help_says_it_runs_until_stopped(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["serve", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "default: run until stopped" in text
    assert "default 14400" not in text


def test_fly_keeps_its_four_hour_default(tmp_path: Path) -> None:
    args = build_parser().parse_args(["fly", str(tmp_path / "x.plan")])
    assert float(args.max_sim_time) == 14400.0
