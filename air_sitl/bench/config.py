"""What one bench run compares: scenarios, methods, external localizers, where results go.

Parsed once at the edge (``air-sitl bench`` options) into :class:`BenchConfig`; every later
step reads only this.
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from air_sitl.errors import OptionError
from air_sitl.localize.external import ExternalLocalizer

FLIGHT_DATE = 1  # the flight imagery's map date (the default)
REFERENCE_DATE = 0  # what map-matching methods match against
__all__ = [
    "FLIGHT_DATE",
    "REFERENCE_DATE",
    "BenchConfig",
    "ExternalLocalizer",
    "method_problem",
    "parse_localizer",
    "parse_methods",
]
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


@dataclass(frozen=True, slots=True, kw_only=True)
class BenchConfig:
    """One bench: scenarios x (methods + external localizers), results under ``out``."""

    scenarios: tuple[str, ...]
    methods: tuple[str, ...]
    localizers: tuple[ExternalLocalizer, ...] = ()
    out: Path
    jobs: int = 1
    missions: Path
    flight_date: int = FLIGHT_DATE
    reference_date: int = REFERENCE_DATE
    align: str = "none"
    seed: int = 0
    quiet: bool = False
    extra_dataset_args: tuple[str, ...] = field(default_factory=tuple)

    @property
    def archives(self) -> Path:
        return self.out / "archives"

    @property
    def reports(self) -> Path:
        return self.out / "reports"

    @property
    def entries(self) -> tuple[str, ...]:
        """Every column of the leaderboard: built-in methods, then external localizers."""
        return (*self.methods, *(loc.name for loc in self.localizers))


def method_problem(names: Sequence[str], known: Sequence[str]) -> tuple[int, str] | None:
    """The index of the first name that is not a known method or repeats one, and why."""
    for i, name in enumerate(names):
        if name not in known:
            return i, f"unknown method {name!r}; known: {', '.join(known)}"
        if name in names[:i]:
            return i, f"method {name!r} named twice"
    return None


def parse_methods(text: str, known: tuple[str, ...]) -> tuple[str, ...]:
    """``deadreckon,vo`` (or ``all``) -> the method names, each one registered."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["all"]:
        return known
    if not names:
        msg = f"--methods {text!r}: expected a comma-separated list of {', '.join(known)}"
        raise OptionError(msg)
    problem = method_problem(names, known)
    if problem is not None:
        msg = f"--methods {text!r}: {problem[1]}"
        raise OptionError(msg)
    return tuple(names)


def parse_localizer(text: str) -> ExternalLocalizer:
    """``NAME=COMMAND`` -> an external localizer (the command split like a shell would)."""
    name, sep, command = text.partition("=")
    name = name.strip()
    if not sep or not _NAME.fullmatch(name):
        msg = f'--localizer {text!r}: expected NAME=COMMAND, e.g. mine="python my_loc.py"'
        raise OptionError(msg)
    try:
        argv = tuple(shlex.split(command))
    except ValueError as err:
        msg = f"--localizer {name}: cannot split the command {command!r}: {err}"
        raise OptionError(msg) from None
    if not argv:
        msg = f"--localizer {name}: the command is empty"
        raise OptionError(msg)
    return ExternalLocalizer(name=name, argv=argv)
