"""``air-sitl fly BADFILE``: exit code 2 and one line on stderr naming file, item and value."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from .conftest import BASE_PLAN

Doc = dict[str, Any]


def _items(doc: Doc) -> list[Any]:
    items: list[Any] = doc["mission"]["items"]
    return items


def _mutate(change: Callable[[Doc], None]) -> Doc:
    doc: Doc = json.loads(json.dumps(BASE_PLAN))
    change(doc)
    return doc


CASES: list[tuple[str, str | Doc | None, list[str]]] = [
    # (id, file content (None: no file), texts stderr must contain besides the file name)
    ("missing-file", None, ["file not found"]),
    ("not-json", '{"fileType": "Plan",', ["not JSON"]),
    ("wrong-filetype", _mutate(lambda d: d.update(fileType="Mission")), ['"Mission"']),
    ("missing-field", _mutate(lambda d: d["mission"].pop("items")), ['"mission.items"']),
    ("unknown-command", _mutate(lambda d: _items(d)[2].update(command=31337)), ["item 2", "31337"]),
    (
        "latitude",
        _mutate(lambda d: _items(d)[3]["params"].__setitem__(4, 123.25)),
        ["item 3", "latitude", "123.25"],
    ),
    (
        "nan-altitude",
        _mutate(lambda d: _items(d)[2]["params"].__setitem__(6, None)),
        ["item 2", "altitude", "nan"],
    ),
    (
        "jump-target",
        _mutate(lambda d: _items(d)[4]["params"].__setitem__(0, 77)),
        ["item 4", "doJumpId", "77"],
    ),
    ("terrain-frame", _mutate(lambda d: _items(d)[3].update(frame=10)), ["item 3", "terrain"]),
    ("empty-mission", _mutate(lambda d: d["mission"].update(items=[])), ["no navigation item"]),
    (
        "complex-item",
        _mutate(
            lambda d: _items(d).__setitem__(1, {"type": "ComplexItem", "complexItemType": "survey"})
        ),
        ["item 1", "survey"],
    ),
    ("wpl-malformed", "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\n", ["line 2", "found 7"]),
]


@pytest.mark.integration
@pytest.mark.parametrize(("content", "expected"), [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_fly_refuses_bad_plans_with_one_line(
    tmp_path: Path, content: str | Doc | None, expected: list[str]
) -> None:
    plan = tmp_path / "broken-plan.plan"
    if isinstance(content, str):
        plan.write_text(content, encoding="utf-8")
    elif content is not None:
        plan.write_text(json.dumps(content, indent=4), encoding="utf-8")
    out = tmp_path / "out"
    result = subprocess.run(
        [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(out), "--no-camera"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=tmp_path,
    )
    assert result.returncode == 2, result.stderr
    assert "Traceback" not in result.stderr
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr
    assert "broken-plan.plan" in lines[0]
    for text in expected:
        assert text in lines[0], lines[0]
