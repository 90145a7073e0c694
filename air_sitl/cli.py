"""The ``air-sitl`` command: parses, dispatches to one module per command, prints errors.

Each command module in :mod:`air_sitl.commands` has ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int``. A command module imports at its top only
what its arguments need (light modules: no numpy, OpenCV, rasterio, zenoh, JSBSim ...) and the
rest inside ``run``: ``--help``, ``--version`` and a command's ``--help`` answer at once
(``benchmarks/bench_cli.py``). A mistake on the command line is one line naming the option
and the value and where the help is, exit 2, as every other error.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import NoReturn

from air_sitl import __version__
from air_sitl.errors import AirSitlError

# command name -> module under air_sitl.commands
COMMANDS: dict[str, str] = {
    "fly": "fly",
    "serve": "serve",
    "dataset": "dataset",
    "check": "check",
    "export": "export",
    "eval": "eval",
    "localize": "localize",
    "bench": "bench",
    "sweep": "sweep",
    "render": "render",
    "map": "map_make",
    "camera-bridge": "camera_bridge",
    "router": "router",
}


TOP_LEVEL_OPTIONS = ("-h", "--help", "--version")


def _load(module: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"air_sitl.commands.{module}")
    except ModuleNotFoundError as err:
        if err.name == f"air_sitl.commands.{module}":
            return None  # command not built yet
        raise


class Parser(argparse.ArgumentParser):
    """argparse's parser whose errors are one line, as the rest of air-sitl's.

    ``air-sitl: error: fly: argument --map-date: invalid int value: 'x' (see `air-sitl fly
    --help`)`` and exit 2, instead of argparse's usage block. Subcommands' parsers are of
    this class too (argparse makes them of the parent's class).
    """

    def error(self, message: str) -> NoReturn:
        """Print the one line and exit 2."""
        command = self.prog.removeprefix("air-sitl").strip()
        where = f"{command}: " if command else ""
        self.exit(2, f"air-sitl: error: {where}{message} (see `{self.prog} --help`)\n")


def _parser_for(parser: argparse.ArgumentParser, argv: Sequence[str]) -> argparse.ArgumentParser:
    """The (sub)command parser ``argv`` names: ``fly``, ``map make`` ..., else ``parser``."""
    for token in argv:
        subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
        if subs and token in subs[0].choices:
            parser = subs[0].choices[token]
    return parser


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every available command, or with the command ``only``."""
    parser = Parser(
        prog="air-sitl",
        description="Fixed-wing UAV software-in-the-loop for map-based localization research.",
    )
    parser.add_argument("--version", action="version", version=f"air-sitl {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module_name in COMMANDS.items():
        if only is not None and name != only:
            continue
        module = _load(module_name)
        if module is None:
            continue
        cmd = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``air-sitl`` console script."""
    argv = list(sys.argv[1:] if argv is None else argv)
    # Lazy on purpose: running a command imports its module alone (and its dependencies), not
    # every command's; the overall --help and errors before a command load them all.
    first = argv[0] if argv else None
    only = first if first in COMMANDS and _load(COMMANDS[first]) is not None else None
    parser = build_parser(only)
    try:
        if first is not None and first.startswith("-") and first not in TOP_LEVEL_OPTIONS:
            # argparse would first report the missing COMMAND: name what was mistyped
            parser.error(f"unrecognized arguments: {first}")
        args, extra = parser.parse_known_args(argv)
        if extra:  # argparse reports these on the top parser: name the command they went to
            _parser_for(parser, argv).error(f"unrecognized arguments: {' '.join(extra)}")
    except SystemExit as done:  # --help, --version (0) or a mistake (2): a return code
        return done.code if isinstance(done.code, int) else 2
    try:
        code: int = args._run(args)
    except AirSitlError as err:
        print(f"air-sitl: error: {err}", file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print("air-sitl: interrupted", file=sys.stderr)
        return 130
    return code


if __name__ == "__main__":
    sys.exit(main())
