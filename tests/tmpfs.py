"""Real small or read-only file systems for the disk-fault tests: a tmpfs mounted for the test.

``mount -t tmpfs`` needs root (or CAP_SYS_ADMIN); where it is refused the test is skipped with
the reason. Unmounted (lazily, so a process still holding a file cannot keep it) at the end.
"""

from __future__ import annotations

import contextlib
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest


@contextlib.contextmanager
def tmpfs(folder: Path, *, size: str = "4m", read_only: bool = False) -> Iterator[Path]:
    """Mount a tmpfs of ``size`` at ``folder`` (created) for the block; skip when refused."""
    folder.mkdir(parents=True, exist_ok=True)
    options = f"size={size}" + (",ro" if read_only else "")
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(folder)],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip() or done.returncode}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", "-l", str(folder)], capture_output=True, check=False)


def remount_read_only(folder: Path) -> None:
    """Turn a mounted tmpfs read-only (what a failing disk does mid-flight)."""
    subprocess.run(["mount", "-o", "remount,ro", str(folder)], check=True, capture_output=True)
