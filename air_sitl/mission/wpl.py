"""The ``QGC WPL 110`` text format: one tab-separated line per item, line 0 is home.

The public entry points are in :mod:`air_sitl.mission.plan_file`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from air_sitl.errors import PlanError
from air_sitl.mission.items import MavCmd, Mission, MissionItem
from air_sitl.mission.reading import PathLike
from air_sitl.state import GeoPoint

WPL_HEADER = "QGC WPL 110"
WPL_COLUMNS = (
    "seq",
    "current",
    "frame",
    "command",
    "param1",
    "param2",
    "param3",
    "param4",
    "x/latitude",
    "y/longitude",
    "z/altitude",
    "autocontinue",
)

_T = TypeVar("_T", int, float)


def wpl_from_text(text: str, path: PathLike) -> tuple[Mission, list[str]]:
    """Parse WPL text; also return ``"item i (line n)"`` labels for messages."""
    # Blank lines and "#" comment lines are skipped, as QGroundControl and MAVProxy do.
    content = [
        (number, line.strip())
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    first, header = content[0] if content else (1, "")
    if header != WPL_HEADER:
        msg = f'{path}: line {first}: expected the header "{WPL_HEADER}" ({header!r})'
        raise PlanError(msg)
    rows: list[tuple[int, list[str]]] = [(number, line.split()) for number, line in content[1:]]
    if not rows:
        msg = f"{path}: no home line after the header, expected seq 0 = home position"
        raise PlanError(msg)
    parsed: list[tuple[int, tuple[int, int, int, int], list[float], bool]] = []
    for expected_seq, (number, cols) in enumerate(rows):
        where = f"{path}: line {number}"
        if len(cols) != len(WPL_COLUMNS):
            msg = (
                f"{where}: expected {len(WPL_COLUMNS)} tab-separated columns "
                f"({' '.join(WPL_COLUMNS)}), found {len(cols)} ({' '.join(cols)[:60]!r})"
            )
            raise PlanError(msg)
        ints = _columns(cols, range(4), int, "an integer", where)
        floats = _columns(cols, range(4, 11), float, "a number", where)
        if cols[11] not in ("0", "1"):
            msg = f"{where}: column autocontinue must be 0 or 1 ({cols[11]!r})"
            raise PlanError(msg)
        if ints[0] != expected_seq:
            msg = f"{where}: sequence number out of order, expected {expected_seq} ({ints[0]})"
            raise PlanError(msg)
        parsed.append((number, (ints[0], ints[1], ints[2], ints[3]), floats, cols[11] == "1"))

    _, _, home, _ = parsed[0]
    items: list[MissionItem] = []
    labels: list[str] = []
    count = len(parsed) - 1
    for index, (number, (_seq, _current, frame, command), p, autocontinue) in enumerate(parsed[1:]):
        param1 = p[0]
        if command == MavCmd.DO_JUMP:
            # WPL counts home as seq 0: target seq s is mission index s - 1.
            if not (math.isfinite(param1) and param1 == int(param1) and 1 <= param1 <= count):
                msg = (
                    f"{path}: item {index} (line {number}): DO_JUMP target is not an item "
                    f"sequence number, expected 1..{count} ({param1})"
                )
                raise PlanError(msg)
            param1 -= 1.0
        items.append(
            MissionItem.from_params(
                command, frame, (param1, *p[1:7]), autocontinue=autocontinue, seq=index
            )
        )
        labels.append(f"item {index} (line {number})")
    mission = Mission(
        items=tuple(items),
        planned_home=GeoPoint(lat_deg=home[4], lon_deg=home[5], alt_amsl_m=home[6]),
        source=str(path),
        name=Path(path).stem,
    )
    return mission, labels


def _columns(
    cols: list[str], span: range, convert: Callable[[str], _T], expected: str, where: str
) -> list[_T]:
    """Columns ``span`` of one line converted, or the error naming the first bad column."""
    out: list[_T] = []
    for col in span:
        try:
            out.append(convert(cols[col]))
        except ValueError:
            msg = f"{where}: column {WPL_COLUMNS[col]} must be {expected} ({cols[col]!r})"
            raise PlanError(msg) from None
    return out
