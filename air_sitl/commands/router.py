"""``air-sitl router``: a zenoh router for multi-host setups (zenoh-python in router mode).

Simulators, camera bridges and estimators on other hosts connect to it
(``--zenoh-connect tcp/HOST:7447``) instead of to each other. Runs until SIGINT or SIGTERM.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from air_sitl.bus.defaults import DEFAULT_ENDPOINT
from air_sitl.errors import OptionError

HELP = "run a zenoh router that simulators, camera bridges and estimators connect to"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``router``."""
    parser.add_argument(
        "--listen",
        action="append",
        metavar="ENDPOINT",
        help=f"zenoh endpoint to listen on, repeatable (default {DEFAULT_ENDPOINT}; "
        "tcp/0.0.0.0:7447 to accept other hosts)",
    )
    parser.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh JSON5 config (TLS, access control ...); --listen applies on top",
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")


def run(args: argparse.Namespace) -> int:
    """Route until interrupted; exit 0 on SIGINT/SIGTERM."""
    from air_sitl.bus.session import BusConfig, open_bus
    from air_sitl.bus.signals import wait_until_signalled

    config_file = Path(args.zenoh_config) if args.zenoh_config else None
    if config_file is not None and not config_file.is_file():
        msg = f"--zenoh-config {config_file}: no such file"
        raise OptionError(msg)
    listen = tuple(args.listen) if args.listen else None
    if listen is None and config_file is None:
        listen = (DEFAULT_ENDPOINT,)
    cfg = BusConfig(mode="router", listen=listen, connect=(), config_file=config_file, serves=True)
    with open_bus(cfg) as bus:
        if not args.quiet:
            where = ", ".join(listen) if listen else "the config's endpoints"
            print(f"air-sitl router: {bus.zid} listening on {where}", flush=True)
        wait_until_signalled()
        if not args.quiet:
            print("air-sitl router: stopped", flush=True)
    return 0
