"""docs/ci.md's workflow is valid YAML for GitHub Actions and every air-sitl line in it parses.

The commands themselves run in the README tour's test (fly, localize, eval --require); this
keeps the page's copy of them from drifting away from the options the CLI has.
"""

from __future__ import annotations

import re
import shlex
import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml

from air_sitl.cli import build_parser

PAGE = Path(__file__).resolve().parents[2] / "docs" / "ci.md"


def blocks() -> list[object]:
    """The page's yaml blocks, loaded: the whole workflow, then step lists to add to it."""
    text = PAGE.read_text(encoding="utf-8")
    found = re.findall(r"```yaml\n(.*?)```", text, re.DOTALL)
    return [yaml.safe_load(textwrap.dedent(block)) for block in found]


def workflow() -> dict[str, Any]:
    first = blocks()[0]
    assert isinstance(first, dict)
    return first


def commands() -> list[list[str]]:
    """Every air-sitl command run by a step of the page (shell continuation lines joined)."""
    found = []
    for block in blocks():
        steps = block["jobs"]["fly"]["steps"] if isinstance(block, dict) else block
        assert isinstance(steps, list)
        for step in steps:
            script = str(step.get("run", "")).replace("\\\n", " ")
            for line in script.splitlines():
                if line.strip().startswith("air-sitl "):
                    argv = shlex.split(line.split(" & ")[0], comments=True)
                    found.append(argv[1:])
    return found


def test_the_workflow_uploads_artifacts_and_gates_on_eval() -> None:
    steps = workflow()["jobs"]["fly"]["steps"]
    runs = " ".join(str(s.get("run", "")) for s in steps)
    assert "air-sitl fly" in runs and "air-sitl eval" in runs and "--require" in runs
    uploads = [s for s in steps if str(s.get("uses", "")).startswith("actions/upload-artifact")]
    assert uploads and uploads[0]["if"] == "always()"


def test_the_page_runs_fly_localize_and_eval() -> None:
    assert {argv[0] for argv in commands()} == {"fly", "localize", "eval"}


@pytest.mark.parametrize("argv", commands(), ids=lambda a: " ".join(a[:2]))
def test_every_command_on_the_page_parses(argv: list[str]) -> None:
    args = build_parser().parse_args(argv)
    assert args.command == argv[0]
