"""The ``air-sitl`` command: parses, dispatches to one module per command, prints errors.

Each command module in :mod:`air_sitl.commands` has ``HELP`` (one line),
``add_arguments(parser)`` and ``run(args) -> int``. Modules import their heavy dependencies
inside ``run`` so that ``air-sitl --help`` stays fast.
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


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser with every available command."""
    parser = argparse.ArgumentParser(
        prog="air-sitl",
        description="Fixed-wing UAV software-in-the-loop for map-based localization research.",
    )
    parser.add_argument("--version", action="version", version=f"air-sitl {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for name, module_name in COMMANDS.items():
        module = _load(module_name)
        if module is None:
            continue
        cmd = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(cmd)
        cmd.set_defaults(_run=module.run)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``air-sitl`` console script."""
    parser = build_parser()
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
