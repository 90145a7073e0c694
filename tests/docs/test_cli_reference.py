"""docs/cli.md is what the argparse parsers say: an option changed without the page fails CI."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "docs" / "gen_cli_reference.py"


def _check() -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), "--check"],
        cwd=REPO, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip


def test_the_cli_reference_is_current() -> None:
    run = _check()
    assert run.returncode == 0, run.stderr


def test_every_command_and_option_is_on_the_page() -> None:
    from air_sitl.cli import COMMANDS, build_parser

    page = (REPO / "docs" / "cli.md").read_text(encoding="utf-8")
    for name in COMMANDS:
        assert f"## `air-sitl {name}`" in page, name
    parser = build_parser("fly")
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for action in sub.choices["fly"]._actions:
        for option in action.option_strings:
            if option not in ("-h", "--help"):
                assert f"`{option}`" in page, option
