"""``air-sitl serve`` refuses bad options with one line and exit code 2."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from cli_errors import one_line_error
from ports import free_port

from air_sitl.cli import main


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--mavlink", "serial:/dev/ttyS0"], "--mavlink 'serial:/dev/ttyS0': expected udpout"),
        (["--mavlink", "udpin::14550"], "give the address explicitly"),
        (["--signing-key", "abc"], "--signing-key: expected 64 hex digits"),
        (["--home", "91,0,0"], "--home '91,0,0': latitude must be in [-90, 90]"),
        (["--home", "a,b"], "expected LAT,LON,ALT_AMSL"),
        (["--plan", "no/such.plan"], "no/such.plan"),
        (["--air-start"], "--air-start: serve starts on the ground"),
        (["--speed", "-1"], "--speed"),
    ],
)
def test_bad_options_exit_2_with_one_line(
    args: list[str], expected: str, capsys: pytest.CaptureFixture[str]
) -> None:
    err = one_line_error(["serve", "--mavlink", "udpin:127.0.0.1:0", *args], capsys)
    assert expected in err, err


@pytest.mark.parametrize("kind", ["udpin", "tcpin"])
def test_a_port_in_use_is_a_one_line_error(kind: str, capsys: pytest.CaptureFixture[str]) -> None:
    udp = kind == "udpin"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM if udp else socket.SOCK_STREAM) as taken:
        taken.bind(("127.0.0.1", 0))
        if not udp:
            taken.listen()
        port = taken.getsockname()[1]
        video = f"udp://127.0.0.1:{free_port(socket.SOCK_DGRAM)}"  # never sent to: no vehicle
        argv = ["serve", "--mavlink", f"{kind}:127.0.0.1:{port}", "--video", video]
        assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err.startswith("air-sitl: error: ") and err.count("\n") == 1, err
    assert f"{kind}:127.0.0.1:{port}: cannot " in err and "in use" in err, err
    # The error alone: no "video: 0 frames sent" summary of a stream that never ran.
    assert out == "", out


def test_signing_key_file_is_read(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    missing = tmp_path / "nokey"
    argv = ["serve", "--mavlink", "udpin:127.0.0.1:0", "--signing-key", f"@{missing}"]
    assert "cannot read the key file" in one_line_error(argv, capsys)
