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
    from air_sitl.cli import build_parser

    page = (REPO / "docs" / "cli.md").read_text(encoding="utf-8")
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    assert len(sub.choices) >= 13  # fly, serve, dataset ... router
    for name, command in sub.choices.items():
        assert f"## `air-sitl {name}`" in page, name
        for action in command._actions:
            for option in action.option_strings:
                if option not in ("-h", "--help"):
                    assert f"`{option}`" in page, f"{name} {option}"
