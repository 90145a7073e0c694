"""``serve`` without ``--plan`` or ``--home`` says where it puts the vehicle (issue 25)."""

from __future__ import annotations

from typing import Any

import pytest

from air_sitl import serving
from air_sitl.cli import main


def _serve(monkeypatch: pytest.MonkeyPatch, *argv: str) -> Any:
    seen: dict[str, Any] = {}

    class _Counters:
        messages = dropped = parse_errors = unknown_ids = signature_rejected = kernel_dropped = 0
        kernel_drops_counted = False

    def fake_serve(setup: Any, specs: object, **kw: Any) -> _Counters:
        seen["home"] = setup.home
        return _Counters()

    monkeypatch.setattr(serving, "serve_vehicle", fake_serve)  # no sockets: the setup only
    assert main(["serve", "--mavlink", "udpout:127.0.0.1:1", *argv]) == 0
    return seen["home"]


def test_the_default_home_is_said(capsys: pytest.CaptureFixture[str]) -> None:
    """A real served vehicle (its link on a free port), for a simulated half second."""
    argv = ["serve", "--mavlink", "udpin:127.0.0.1:0", "--no-video", "--max-sim-time", "0.5"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert (
        "vehicle ready at 47.3977420,8.5455940,488.0 (no --plan or --home: PX4 SITL's default "
        "home, Zurich) speed"
    ) in out
    assert main([*argv, "--instance", "2"]) == 0
    assert "Zurich, 40 m east for instance 2) speed" in capsys.readouterr().out


def test_the_default_home_is_px4s(monkeypatch: pytest.MonkeyPatch) -> None:
    home = _serve(monkeypatch)
    assert (home.lat_deg, home.lon_deg) == (47.397742, 8.545594)


def test_a_given_home_is_not_announced(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["serve", "--mavlink", "udpin:127.0.0.1:0", "--no-video", "--max-sim-time", "0.5"]
    assert main([*argv, "--home", "46.5,7.5,600"]) == 0
    out = capsys.readouterr().out
    assert "vehicle ready at 46.5000000,7.5000000,600.0 speed" in out
    assert "default" not in out
    home = _serve(monkeypatch, "--home", "46.5,7.5,600")
    assert (home.lat_deg, home.lon_deg) == (46.5, 7.5)
