"""Atomic file writes: a temporary name beside the target, then a rename into place.

A reader (or a crash) never sees half a file: the target holds the old content or the new one.
Every writer of an archive file (JPEG frames, camera.yaml, summary and manifest JSON, the
rewritten ``metadata.csv``) goes through here.
"""

from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path
from typing import Any

from air_sitl.errors import DatasetError

TMP_SUFFIX = ".tmp"  # the temporary name of a file being written: <name>.tmp


def write_error(path: str | os.PathLike[str], err: OSError) -> DatasetError:
    """The one-line error of a failed write of ``path``."""
    return DatasetError(f"{os.fspath(path)}: cannot write: {err.strerror or err}")


def write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte of ``data`` is written (short writes happen)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes, *, fsync: bool = False) -> None:
    """Write ``data`` to ``<path>.tmp`` and rename it to ``path`` (DatasetError on failure).

    ``fsync`` forces the bytes to disk before the rename. The temporary name never stays.
    """
    final = os.fspath(path)
    tmp = final + TMP_SUFFIX
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            write_all(fd, data)
            if fsync:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, final)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise write_error(final, err) from None


def write_json_atomic(path: Path, content: Any) -> None:
    """Write ``content`` as indented JSON, synced to disk, atomically (DatasetError on failure)."""
    write_bytes_atomic(path, (json.dumps(content, indent=2) + "\n").encode("utf-8"), fsync=True)
