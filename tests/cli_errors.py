"""The command line's user errors: exit code 2 and one ``air-sitl: error:`` line."""

from __future__ import annotations

import pytest

from air_sitl.cli import main


def one_line_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``air-sitl ARGV`` in this process; it must exit 2 with one error line on stderr
    (and nothing else there since the last read of ``capsys``). That line, stripped."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("air-sitl: error: ") and err.count("\n") == 1, err
    return err.strip()
