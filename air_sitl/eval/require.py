"""``--require 'horizontal_error_m.rmse<=20'``: requirements on report figures (the CI gate).

A requirement is a dotted path into the report, an operator (<=, <, >=, >, ==) and a number.
A bad expression or an unknown key is a user error (:class:`~air_sitl.errors.OptionError`); a
figure that is null fails the requirement.
"""

from __future__ import annotations

import math
import operator
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from air_sitl.errors import OptionError
from air_sitl.eval.report import lookup

_OPS: dict[str, Callable[[float, float], bool]] = {
    "<=": operator.le,
    ">=": operator.ge,
    "==": operator.eq,
    "<": operator.lt,
    ">": operator.gt,
}
_EXPR = re.compile(r"^\s*([A-Za-z0-9_.]+)\s*(<=|>=|==|<|>)\s*(\S+)\s*$")


@dataclass(frozen=True, slots=True, kw_only=True)
class Requirement:
    """One parsed ``--require`` expression."""

    text: str
    path: str
    op: str
    value: float

    def check(self, report: dict[str, Any]) -> str | None:
        """None when ``report`` meets it, else one line naming the estimate and the figure."""
        try:
            figure = lookup(report, self.path)
        except KeyError as err:
            msg = (
                f"--require {self.text!r}: the report has no key {err.args[0]!r} ({self.path}); "
                f"the keys: {', '.join(numeric_keys(report))}"
            )
            raise OptionError(msg) from None
        if isinstance(figure, (dict, str, bool)):
            msg = f"--require {self.text!r}: {self.path} is not a number"
            raise OptionError(msg)
        name = report.get("estimate")
        if figure is None:
            return (
                f"{name}: {self.path} is null (not computable), required {self.op} {self.value:g}"
            )
        if _OPS[self.op](float(figure), self.value):
            return None
        return f"{name}: {self.path} = {float(figure):.6g}, required {self.op} {self.value:g}"


def numeric_keys(report: dict[str, Any], prefix: str = "") -> list[str]:
    """The dotted paths of a report's figures (numbers or null), what ``--require`` takes."""
    keys = []
    for key, value in report.items():
        if isinstance(value, dict):
            keys += numeric_keys(value, f"{prefix}{key}.")
        elif key == "v" and not prefix:
            continue  # the contract's version, not a figure
        elif value is None or (isinstance(value, int | float) and not isinstance(value, bool)):
            keys.append(f"{prefix}{key}")
    return keys


def parse(text: str) -> Requirement:
    """Parse ``PATH OP NUMBER`` (OptionError when it is not one)."""
    m = _EXPR.match(text)
    if m is None:
        msg = (
            f"--require {text!r}: expected PATH OP NUMBER, e.g. 'horizontal_error_m.rmse<=20' "
            "(operators <=, <, >=, >, ==)"
        )
        raise OptionError(msg)
    path, op, number = m.groups()
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        msg = f"--require {text!r}: {number!r} is not a finite number"
        raise OptionError(msg)
    return Requirement(text=text, path=path, op=op, value=value)


def failures(requirements: Sequence[Requirement], reports: Sequence[dict[str, Any]]) -> list[str]:
    """One line per (report, requirement) that fails; every report must meet every one."""
    out: list[str] = []
    for report in reports:
        for req in requirements:
            line = req.check(report)
            if line is not None:
                out.append(line)
    return out


def met(requirements: Sequence[Requirement], reports: Sequence[dict[str, Any]]) -> list[str]:
    """One line per (report, requirement) that holds, with its figure: the gate's confirmation."""
    return [
        f"{report.get('estimate')}: {req.path} = {float(lookup(report, req.path)):.6g}, "
        f"required {req.op} {req.value:g}"
        for report in reports
        for req in requirements
        if req.check(report) is None
    ]
