"""results.jsonl: whole lines, a torn last line trimmed, the last row of an id counts."""

from __future__ import annotations

import json
from pathlib import Path

from air_sitl.sweep.results import ROW_KEYS, ResultsFile, comparable, latest_rows, read_rows


def row(ident: str, error: str | None = None) -> dict[str, object]:
    return {"id": ident, "options": {"seed": 1}, "summary": {}, "eval": {}, "error": error,
            "wall_s": 1.0, "host": "h", "archive": f"runs/{ident}"}  # fmt: skip


def test_rows_are_lines_in_order_with_every_key(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    with ResultsFile(path) as results:
        results.append(row("a"))
        results.append({"id": "b"})
    lines = path.read_bytes().split(b"\n")
    assert lines[-1] == b"" and len(lines) == 3
    assert list(json.loads(lines[1])) == list(ROW_KEYS)
    assert [r["id"] for r in read_rows(path)] == ["a", "b"]


def test_a_torn_last_line_is_ignored_then_trimmed(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    with ResultsFile(path) as results:
        results.append(row("a"))
    whole = path.read_bytes()
    path.write_bytes(whole + b'{"id": "b", "opt')
    assert [r["id"] for r in read_rows(path)] == ["a"]
    with ResultsFile(path) as results:
        assert path.read_bytes() == whole
        results.append(row("c"))
    assert [r["id"] for r in read_rows(path)] == ["a", "c"]
    path.write_bytes(b'{"id": "torn')  # nothing but a torn line
    with ResultsFile(path):
        assert path.read_bytes() == b""


def test_the_last_row_of_an_id_counts(tmp_path: Path) -> None:
    path = tmp_path / "results.jsonl"
    with ResultsFile(path) as results:
        results.append(row("a", error="boom"))
        results.append(row("a"))
    assert latest_rows(path)["a"]["error"] is None
    assert "wall_s" not in comparable(row("a")) and "host" not in comparable(row("a"))
