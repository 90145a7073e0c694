"""What scores a run besides the truth: built-in methods and external localizer programs.

Parsed from ``air-sitl bench``'s ``--methods``/``--localizer`` options and from a sweep SPEC's
``methods``/``localizers`` keys alike: a method name must be registered and named once, a
localizer is ``NAME=COMMAND`` (the command split like a shell would).
"""

from __future__ import annotations

import re
import shlex
from collections.abc import Sequence

from air_sitl.errors import OptionError
from air_sitl.localize.external import ExternalLocalizer

__all__ = ["method_problem", "parse_localizer", "parse_methods"]
_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


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
