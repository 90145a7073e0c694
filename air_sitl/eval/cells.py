"""Cells of estimate files, checked one by one: a bad value is an :class:`EvalError` naming
the file, the line, the column and the value (what :mod:`air_sitl.eval.sources` falls back on
to name the first bad line)."""

from __future__ import annotations

import math
from collections.abc import Sequence

from air_sitl.eval.errors import EvalError
from air_sitl.eval.trajectory import NO_TIME

NAN_WORDS = ("", "nan")

Triple = tuple[float, float, float]


def number(text: str, where: str, line: int, column: str) -> float:
    """A finite float, or NaN for an empty / ``nan`` cell; anything else is an error."""
    t = text.strip()
    if t.lower() in NAN_WORDS:
        return math.nan
    try:
        value = float(t)
    except ValueError:
        msg = f"{where}: line {line}: {column} {text!r} is not a number"
        raise EvalError(msg) from None
    if not math.isfinite(value):
        msg = f"{where}: line {line}: {column} {text!r} is not a finite number"
        raise EvalError(msg)
    return value


def integer(text: str, where: str, line: int, column: str) -> int | None:
    t = text.strip()
    if t == "":
        return None
    try:
        return int(t)
    except ValueError:
        msg = f"{where}: line {line}: {column} {text!r} is not an integer"
        raise EvalError(msg) from None


def triple(cells: Sequence[str], columns: Sequence[str], where: str, line: int) -> Triple | None:
    """Three position cells: all numbers, or all empty/nan (None); a mix is an error."""
    values = [number(c, where, line, col) for c, col in zip(cells, columns, strict=True)]
    finite = [math.isfinite(v) for v in values]
    if all(finite):
        return (values[0], values[1], values[2])
    if any(finite):
        shown = ",".join(c.strip() or "''" for c in cells)
        msg = (
            f"{where}: line {line}: {','.join(columns)} = {shown}: some but not all "
            "position columns are empty or nan"
        )
        raise EvalError(msg)
    return None


def check_time_order(t_ns: list[int], lines: list[int], where: str) -> None:
    prev_t, prev_line = None, 0
    for t, line in zip(t_ns, lines, strict=True):
        if t == NO_TIME:
            continue
        if prev_t is not None and t <= prev_t:
            msg = (
                f"{where}: line {line}: time {t} ns is not after {prev_t} ns (line {prev_line}): "
                "times out of order"
            )
            raise EvalError(msg)
        prev_t, prev_line = t, line
