"""Fixtures for mission tests: a valid QGC plan document to mutate, and a writer for it."""

from __future__ import annotations

import copy
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

HOME = [47.397742, 8.545594, 488.0]


def _item(command: int, frame: int, params: list[float | None], jump_id: int) -> dict[str, Any]:
    return {
        "autoContinue": True,
        "command": command,
        "doJumpId": jump_id,
        "frame": frame,
        "params": params,
        "type": "SimpleItem",
    }


BASE_PLAN: dict[str, Any] = {
    "fileType": "Plan",
    "geoFence": {
        "circles": [
            {"circle": {"center": [47.39, 8.54], "radius": 1500}, "inclusion": True, "version": 1}
        ],
        "polygons": [
            {
                "inclusion": False,
                "polygon": [[47.40, 8.55], [47.41, 8.55], [47.41, 8.56]],
                "version": 1,
            }
        ],
        "breachReturn": [47.3975, 8.5455, 120],
        "version": 2,
    },
    "groundStation": "QGroundControl",
    "mission": {
        "cruiseSpeed": 15,
        "firmwareType": 12,
        "hoverSpeed": 5,
        "items": [
            _item(22, 3, [15, 0, 0, None, 47.3985, 8.5456, 100], 1),
            _item(178, 2, [1, 15, -1, 0, 0, 0, 0], 2),
            _item(16, 3, [0, 0, 0, None, 47.4005, 8.5460, 100], 3),
            _item(16, 3, [0, 0, 0, None, 47.4005, 8.5500, 100.5], 4),
            _item(177, 2, [3, 1, 0, 0, 0, 0, 0], 5),
            _item(2000, 2, [0, 0.02, 0, None, None, None, None], 6),
            _item(18, 3, [1, 0, 150, 0, 47.4020, 8.5480, 120], 7),
            _item(2001, 2, [0, None, None, None, None, None, None], 8),
            _item(20, 2, [0, 0, 0, 0, 0, 0, 0], 9),
        ],
        "plannedHomePosition": HOME,
        "vehicleType": 1,
        "version": 2,
    },
    "rallyPoints": {"points": [[47.3960, 8.5430, 80], [47.3990, 8.5470, 90]], "version": 2},
    "version": 1,
}

PlanWriter = Callable[..., Path]


@pytest.fixture
def base_plan() -> dict[str, Any]:
    """A fresh deep copy of a valid QGC plan document, free to mutate."""
    return copy.deepcopy(BASE_PLAN)


@pytest.fixture
def write_doc(tmp_path: Path) -> PlanWriter:
    """Write a JSON document (or raw text) to ``tmp_path / name`` and return the path."""

    def write(doc: object, name: str = "test.plan") -> Path:
        path = tmp_path / name
        text = doc if isinstance(doc, str) else json.dumps(doc, indent=4)
        path.write_text(text, encoding="utf-8")
        return path

    return write
