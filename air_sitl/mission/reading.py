"""What both plan readers share: the file's text, and typed access to JSON fields, with every
error a one-line :class:`~air_sitl.errors.PlanError` naming the file, the place and the value.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any, NoReturn

from air_sitl.errors import PlanError

PathLike = str | os.PathLike[str]


def read_text(path: PathLike) -> str:
    """The UTF-8 text of a plan file (a BOM is dropped)."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        msg = f"{path}: file not found"
        raise PlanError(msg) from None
    except IsADirectoryError:
        msg = f"{path}: is a folder, expected a .plan or QGC WPL file"
        raise PlanError(msg) from None
    except OSError as err:
        msg = f"{path}: cannot read: {err.strerror}"
        raise PlanError(msg) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        msg = f"{path}: not a text file, expected UTF-8 JSON or QGC WPL (byte {err.start})"
        raise PlanError(msg) from None


def _type_name(value: object) -> str:
    return {
        dict: "object",
        list: "array",
        str: "string",
        bool: "boolean",
        int: "number",
        float: "number",
        type(None): "null",
    }.get(type(value), type(value).__name__)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


class JsonObject:
    """Typed access to one JSON object, with errors naming the file, the place and the field."""

    def __init__(self, obj: object, path: PathLike, where: str, field_prefix: str = "") -> None:
        self.path = path
        self.where = where  # "item 3", "" for file level
        self.prefix = field_prefix  # "mission." for nested file-level fields
        if not isinstance(obj, dict):
            self.fail(f"expected a JSON object ({_type_name(obj)})")
        self.obj: dict[str, Any] = obj

    def fail(self, what: str) -> NoReturn:
        place = f"{self.path}: {self.where}: " if self.where else f"{self.path}: "
        raise PlanError(place + what)

    def has(self, key: str) -> bool:
        return key in self.obj

    def get(self, key: str, expected: str) -> Any:
        if key not in self.obj:
            self.fail(f'missing field "{self.prefix}{key}", expected {expected}')
        return self.obj[key]

    def integer(self, key: str) -> int:
        value = self.get(key, "an integer")
        if not _is_number(value) or not math.isfinite(value) or value != int(value):
            self.fail(f'field "{self.prefix}{key}" must be an integer ({json.dumps(value)})')
        return int(value)

    def number(self, key: str, expected: str = "a number") -> float:
        value = self.get(key, expected)
        if not _is_number(value):
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({json.dumps(value)})')
        return float(value)

    def boolean(self, key: str) -> bool:
        value = self.get(key, "true or false")
        if not isinstance(value, bool):
            self.fail(f'field "{self.prefix}{key}" must be true or false ({json.dumps(value)})')
        return value

    def array(self, key: str, expected: str) -> list[Any]:
        value = self.get(key, expected)
        if not isinstance(value, list):
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({_type_name(value)})')
        return value

    def numbers(self, key: str, count: int, expected: str, *, nulls: bool = False) -> list[float]:
        """An array of exactly ``count`` numbers (``null`` -> NaN when ``nulls``)."""
        values = self.array(key, expected)
        if len(values) != count:
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({len(values)} values)')
        return self.to_floats(key, values, expected, nulls=nulls)

    def to_floats(
        self, key: str, values: list[Any], expected: str, *, nulls: bool = False
    ) -> list[float]:
        out: list[float] = []
        for value in values:
            if value is None and nulls:
                out.append(math.nan)
            elif _is_number(value):
                out.append(float(value))
            else:
                self.fail(
                    f'field "{self.prefix}{key}" must be {expected} ({json.dumps(value)} in it)'
                )
        return out
