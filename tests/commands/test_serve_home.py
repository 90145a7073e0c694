"""``serve`` without ``--plan`` or ``--home`` says where it puts the vehicle (issue 25)."""

from __future__ import annotations

from typing import Any

import pytest

from air_sitl import serving
from air_sitl.cli import main


def _serve(monkeypatch: pytest.MonkeyPatch, *argv: str) -> Any:
    seen: dict[str, Any] = {}

    class _Counters:
        messages = dropped = parse_errors = unknown_ids = signature_rejected = 0

    def fake_serve(setup: Any, specs: object, **kw: Any) -> _Counters:
        seen["home"] = setup.home
        return _Counters()

    monkeypatch.setattr(serving, "serve_vehicle", fake_serve)  # no sockets: the setup only
    assert main(["serve", "--mavlink", "udpout:127.0.0.1:1", *argv]) == 0
    return seen["home"]


def test_the_default_home_is_said(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    home = _serve(monkeypatch)
    err = capsys.readouterr().err
    assert (
        "air-sitl serve: no --plan or --home: home at 47.397742, 8.545594, 488 m AMSL "
        "(PX4 SITL's default, Zurich)\n"
    ) in err
    assert (home.lat_deg, home.lon_deg) == (47.397742, 8.545594)


def test_a_given_home_is_not_announced(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    home = _serve(monkeypatch, "--home", "46.5,7.5,600")
    assert "default" not in capsys.readouterr().err
    assert (home.lat_deg, home.lon_deg) == (46.5, 7.5)
    _serve(monkeypatch, "--quiet")
    assert capsys.readouterr().err == ""
