"""Writes docs/cli.md, the command-line reference, from the argparse parsers of ``air-sitl``.

Run ``python docs/gen_cli_reference.py`` after changing an option; ``--check`` exits 1 when
docs/cli.md is not what the parsers say (tests/docs/test_cli_reference.py runs it in CI).
The page is built from the parsers' actions, not from ``--help`` text, so it reads the same
on every Python version and terminal width.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from air_sitl.cli import build_parser

PAGE = Path(__file__).resolve().parent / "cli.md"
HEADER = """# Command-line reference

Generated from the argparse parsers by `docs/gen_cli_reference.py`; do not edit by hand.
Every command also answers `--help`.
"""


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser's subcommands by name, in the order they were added."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _help(action: argparse.Action, prog: str) -> str:
    """The action's help with ``%(default)s`` and friends filled in, as argparse does."""
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    params = {k: v for k, v in vars(action).items() if v is not argparse.SUPPRESS}
    params["prog"] = prog
    if params.get("choices") is not None:
        params["choices"] = ", ".join(str(c) for c in params["choices"])
    return " ".join((action.help % params).split())


def _cell(text: str) -> str:
    """Text for a Markdown table cell: a pipe ends a cell, ``<plan>`` would be an HTML tag."""
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;").replace("|", "\\|")


def _argument(action: argparse.Action) -> str:
    """How the option is written: ``--map MAP``, ``--quiet``, ``{ekf,truth}``."""
    if action.nargs == 0:
        return ""
    if isinstance(action.metavar, tuple):
        return " ".join(action.metavar)  # one name per value already
    if action.metavar is not None:
        metavar = action.metavar
    elif action.choices is not None:
        metavar = "{" + ",".join(str(c) for c in action.choices) + "}"
    else:
        metavar = action.dest.upper()
    if isinstance(action.nargs, int) and action.nargs > 1:
        return " ".join([metavar] * action.nargs)
    return {"?": f"[{metavar}]", "*": f"[{metavar} ...]", "+": f"{metavar} ..."}.get(
        str(action.nargs), metavar
    )


def _command(parser: argparse.ArgumentParser, level: int) -> list[str]:
    lines = [f"{'#' * level} `{parser.prog}`", ""]
    if parser.description:
        text = parser.description[0].upper() + parser.description[1:]
        lines += [_cell(text) + ("" if text.endswith(".") else "."), ""]
    subcommands = _subcommands(parser)
    for group in parser._action_groups:
        rows = []
        for action in group._group_actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if action.help == argparse.SUPPRESS:
                continue
            name = ", ".join(f"`{o}`" for o in action.option_strings) or f"`{action.dest}`"
            arg = _argument(action)
            shown = f"`{_cell(arg)}`" if arg else ""
            rows.append(f"| {name} | {shown} | {_cell(_help(action, parser.prog))} |")
        if rows:
            positional = group.title == "positional arguments"
            title, column = ("arguments", "argument") if positional else (group.title, "option")
            lines += [f"**{title}**", "", f"| {column} | value | what it does |", "|---|---|---|"]
            lines += [*rows, ""]
    for sub in subcommands.values():
        lines += _command(sub, level + 1)
    return lines


def render() -> str:
    """The whole reference page."""
    parser = build_parser()
    lines = [HEADER]
    for sub in _subcommands(parser).values():
        lines += _command(sub, 2)
    return "\n".join(lines).rstrip() + "\n"


def main(argv: list[str]) -> int:
    text = render()
    if argv[1:] == ["--check"]:
        if PAGE.read_text(encoding="utf-8") != text:
            print(f"{PAGE} is stale: run python docs/gen_cli_reference.py", file=sys.stderr)
            return 1
        return 0
    PAGE.write_text(text, encoding="utf-8")
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
