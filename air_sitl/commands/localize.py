"""``air-sitl localize``: run a baseline localizer over an archive, or online on the bus.

Offline: ``air-sitl localize ARCHIVE --method M [--name NAME]`` writes
``ARCHIVE/estimates/NAME.csv`` (the bus recorder's format) and lists it in the manifest.
Online: ``air-sitl localize --bus --method M --name NAME`` joins the bus like
``bridges/example_localizer.py`` (lockstep with ``fly --wait-for NAME``) until the capture
window ends or SIGINT/SIGTERM. The same method objects run in both (:mod:`air_sitl.localize`).
"""

from __future__ import annotations

import argparse
import signal
import threading
from pathlib import Path
from types import FrameType

from air_sitl.bus.args import add_connection_arguments, bus_config_from_args
from air_sitl.bus.keys import KeySpace, check_chunk
from air_sitl.errors import OptionError

HELP = "run a baseline localizer (deadreckon, vo, ...) over an archive or on the zenoh bus"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``localize``."""

    parser.add_argument(
        "archive", nargs="?", metavar="ARCHIVE", help="archive folder (offline; not with --bus)"
    )
    parser.add_argument(
        "--method",
        required=True,
        metavar="M",
        help="deadreckon, vo, mapmatch, mapmatch-axial, fused (any registered method)",
    )
    parser.add_argument(
        "--name", default=None, help="estimator name: estimates/NAME.csv (default: the method)"
    )
    parser.add_argument(
        "--reference-map", default=None, metavar="MAP", help="map to match against (map-based)"
    )
    parser.add_argument(
        "--reference-date", type=int, default=None, metavar="D", help="date of --reference-map"
    )
    parser.add_argument(
        "--seed", type=int, default=0, help="seed of the barometer/airspeed models (default 0)"
    )
    parser.add_argument(
        "--every",
        type=int,
        default=1,
        metavar="K",
        help="mapmatch, fused: match every K-th frame, dead reckoning between (default 1)",
    )
    parser.add_argument(
        "--bus-inputs",
        action="store_true",
        help="offline: give only what the bus carries (no barometer, no airspeed)",
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    g = parser.add_argument_group("online (zenoh bus)")
    g.add_argument("--bus", action="store_true", help="join the bus instead of reading an archive")
    g.add_argument(
        "--gnss",
        choices=("first", "all"),
        default="first",
        help="GNSS given: the fix at the first frame only (default), or every fix the bus "
        "carries (it is silent in denial windows)",
    )
    g.add_argument(
        "--wait",
        type=float,
        default=30.0,
        metavar="S",
        help="seconds to wait for the simulator (default 30)",
    )
    add_connection_arguments(parser, serves=False)


def run(args: argparse.Namespace) -> int:
    """Offline over ``ARCHIVE`` or online with ``--bus``; exit 0 when done."""

    if args.bus:
        if args.archive is not None:
            msg = f"{args.archive}: --bus localizes online; give no ARCHIVE with it"
            raise OptionError(msg)
        return _run_bus(args)
    if args.archive is None:
        msg = "localize: give an ARCHIVE folder, or --bus to localize online"
        raise OptionError(msg)
    return _run_offline(args)


EVERY_METHODS = ("mapmatch", "fused")  # the methods with an ``every`` option


def _method_options(args: argparse.Namespace) -> dict[str, int]:
    """The method's own options from the command line (``--every``)."""

    if args.every == 1:
        return {}
    if args.method not in EVERY_METHODS:
        msg = f"--every {args.every}: only for {', '.join(EVERY_METHODS)}, not {args.method}"
        raise OptionError(msg)
    return {"every": args.every}  # the method refuses an interval below 1


def _run_offline(args: argparse.Namespace) -> int:
    from air_sitl.localize.archive import run_archive
    from air_sitl.progress import Progress

    name = args.name or args.method
    options = _method_options(args)
    bar = Progress(f"localize {name}", None, unit="frames", enabled=not args.quiet)

    def progress(done: int, total: int) -> None:
        if bar.total is None:
            bar.set_total(total)
        bar.update_to(done)

    try:
        result = run_archive(
            Path(args.archive),
            args.method,
            name=args.name,
            reference_map=args.reference_map,
            reference_date=args.reference_date,
            seed=args.seed,
            bus_inputs=args.bus_inputs,
            progress=progress,
            options=options,
        )
    finally:
        bar.close()
    if not args.quiet:
        print(
            f"localize {result.method}: {result.frames} frames, {result.estimated_frames} "
            f"estimated, {result.frames_per_s:.0f} frames/s -> {result.path}",
            flush=True,
        )
    return 0


def _run_bus(args: argparse.Namespace) -> int:
    from air_sitl.bus.session import open_bus
    from air_sitl.localize.methods import make_method
    from air_sitl.localize.online import BusLocalizer

    name = check_chunk("--name", args.name or args.method)
    keys = KeySpace(args.vehicle)
    method = make_method(args.method, **_method_options(args))
    stop = threading.Event()

    def on_signal(_signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with open_bus(bus_config_from_args(args, serves=False)) as bus:
            loc = BusLocalizer(
                bus, keys, method, name, wait_s=args.wait, gnss=args.gnss,
                reference_map=args.reference_map,
                reference_date=None if args.reference_date is None else int(args.reference_date),
            )  # fmt: skip
            if not args.quiet:
                print(f"localize {args.method}: publishing on {loc.key_out}", flush=True)
            loc.run(stop)
            s = loc.summary()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if not args.quiet:
        rate = s["method_frames_per_s"]
        print(
            f"localize {args.method}: {s['frames']} frames, {s['estimated']} estimated"
            + ("" if rate is None else f", method {rate:.0f} frames/s")
            + (f"; callback errors: {s['callback_errors']}" if s["callback_errors"] else ""),
            flush=True,
        )
    return 0
