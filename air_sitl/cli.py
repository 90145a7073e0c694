"""The ``air-sitl`` command: parses, dispatches to one module per command, prints errors.

Each command module in :mod:`air_sitl.commands` has ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int``, and imports what it needs at its top.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from types import ModuleType

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


def _load(module: str) -> ModuleType | None:
    try:
        return importlib.import_module(f"air_sitl.commands.{module}")
    except ModuleNotFoundError as err:
        if err.name == f"air_sitl.commands.{module}":
            return None  # command not built yet
        raise


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The argument parser with every available command, or with the command ``only``."""
    parser = argparse.ArgumentParser(
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
    args = parser.parse_args(argv)
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
