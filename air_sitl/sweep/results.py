"""``results.jsonl``: one JSON line per finished run, appended by the driver alone.

A row is ``{"id", "options", "summary", "eval", "error", "wall_s", "host", "archive",
"reference_date"}``. Each line goes out with one ``os.write`` of the whole line and an fsync,
so a killed sweep leaves whole lines and at most one torn last line, which
:func:`open_results` trims before appending.
A run with a row is done: a re-run skips it (resume). When an id appears twice (a failed run
tried again with ``--retry-failed``), the last row counts.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from air_sitl.closeable import Closeable
from air_sitl.files import write_all
from air_sitl.sweep.errors import SweepError

RESULTS = "results.jsonl"
ROW_KEYS = (
    "id", "options", "summary", "eval", "error", "wall_s", "host", "archive", "reference_date",
    "time_s",
)  # fmt: skip
# What differs between two runs of the same SPEC (time_s: where the run's wall time went).
VOLATILE_KEYS = ("wall_s", "host", "time_s")


def encode_row(row: dict[str, Any]) -> bytes:
    """One row as one line of UTF-8 JSON (keys in :data:`ROW_KEYS` order)."""
    ordered = {k: row.get(k) for k in ROW_KEYS}
    line = json.dumps(ordered, ensure_ascii=False, separators=(", ", ": "), allow_nan=False)
    return (line + "\n").encode("utf-8")


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Every whole row of a results file, in order (a torn last line is ignored)."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as err:
        msg = f"{path}: cannot read: {err.strerror or err}"
        raise SweepError(msg) from None
    end = data.rfind(b"\n") + 1
    rows = []
    for n, line in enumerate(data[:end].splitlines(), start=1):
        if not line.strip():
            continue
        try:
            row = json.loads(line)
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            msg = f"{path}: line {n}: not a JSON row ({err})"
            raise SweepError(msg) from None
        if not isinstance(row, dict) or not isinstance(row.get("id"), str):
            msg = f"{path}: line {n}: not a sweep row (no id)"
            raise SweepError(msg)
        rows.append(row)
    return rows


def latest_rows(path: Path) -> dict[str, dict[str, Any]]:
    """id -> the last row of that id."""
    return {row["id"]: row for row in read_rows(path)}


class ResultsFile(Closeable):
    """The append side of ``results.jsonl``: opened once, a torn last line trimmed first."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            size = os.fstat(self._fd).st_size
            if size:
                tail = os.pread(self._fd, min(size, 1 << 20), max(0, size - (1 << 20)))
                if not tail.endswith(b"\n"):
                    cut = tail.rfind(b"\n")
                    keep = size - len(tail) + cut + 1 if cut >= 0 else 0
                    if cut < 0 and size > len(tail):  # a torn line longer than the tail read
                        keep = self._last_newline(size) + 1
                    os.ftruncate(self._fd, keep)
                    os.fsync(self._fd)
        except OSError as err:
            msg = f"{path}: cannot open for appending: {err.strerror or err}"
            raise SweepError(msg) from None

    def _last_newline(self, size: int) -> int:
        data = os.pread(self._fd, size, 0)
        return data.rfind(b"\n")

    def append(self, row: dict[str, Any]) -> None:
        """Append one row: the whole line in one write, then fsync."""
        line = encode_row(row)
        try:
            os.lseek(self._fd, 0, os.SEEK_END)
            written = os.write(self._fd, line)
            if written < len(line):  # a short write to a regular file: disk full, ...
                write_all(self._fd, line[written:])
            os.fsync(self._fd)
        except OSError as err:
            msg = f"{self.path}: cannot append a row: {err.strerror or err}"
            raise SweepError(msg) from None

    def close(self) -> None:
        os.close(self._fd)


def comparable(row: dict[str, Any]) -> dict[str, Any]:
    """A row without what differs between executors and machines (wall time, host)."""
    return {k: v for k, v in row.items() if k not in VOLATILE_KEYS}
