"""The house rules CI enforces: ruff lint, ruff format and mypy --strict are clean."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
PATHS = ["air_sitl", "bridges", "benchmarks", "tests", "docs"]


def _run(*cmd: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, check=False, timeout=600)


def test_ruff_lint_and_format_are_clean() -> None:
    lint = _run(sys.executable, "-m", "ruff", "check", *PATHS)
    assert lint.returncode == 0, lint.stdout + lint.stderr
    fmt = _run(sys.executable, "-m", "ruff", "format", "--check", *PATHS)
    assert fmt.returncode == 0, fmt.stdout + fmt.stderr


def test_mypy_strict_is_clean() -> None:
    """mypy's incremental cache where the checkout has one (a developer's runs); none written
    where it has none and the environment asks for no written byte code either (CI's fresh
    checkout: writing a cache nobody reads cost about 1 s of the cold check's 11 s of CPU)."""
    cache: list[str] = []
    if not (REPO / ".mypy_cache").is_dir() and os.environ.get("PYTHONDONTWRITEBYTECODE"):
        cache = ["--cache-dir", os.devnull]
    result = _run(sys.executable, "-m", "mypy", *cache)
    assert result.returncode == 0, result.stdout + result.stderr
