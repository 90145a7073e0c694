"""What the commands call: importable without the SDK (it is checked here, with one line)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.errors import OptionError
from air_sitl.foxglove import require_sdk
from air_sitl.state import GeoPoint

if TYPE_CHECKING:
    from air_sitl.bus.hookup import BusHookup
    from air_sitl.camera.model import CameraModel
    from air_sitl.foxglove.live import FoxgloveLive
    from air_sitl.mavlink.vehicle import VehicleEndpoint
    from air_sitl.mission.items import Mission


def export_mcap_command(archive_path: str, out: Path, *, overwrite: bool = False) -> int:
    """``export ARCHIVE --mcap FILE``: write, print the counts; exit 0. An existing FILE is
    refused, or replaced with ``overwrite`` (the one rule of :mod:`air_sitl.outdir`)."""
    require_sdk("--mcap")
    from air_sitl.dataset.reader import open_archive
    from air_sitl.foxglove.record import export_mcap
    from air_sitl.outdir import claim_path
    from air_sitl.progress import Progress

    with open_archive(archive_path) as archive:
        claim_path(out, overwrite=overwrite)
        with Progress(f"export {out.name}", len(archive.rows), unit="frames") as bar:
            counts = export_mcap(archive, out, progress=lambda done, _total: bar.update_to(done))
    total = sum(counts.values())
    detail = ", ".join(f"{t} {n}" for t, n in sorted(counts.items()))
    sys.stdout.write(f"{out}: {total} messages ({detail})\n")
    return 0


DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765  # Foxglove's default
DEFAULT_IMAGE_HZ = 10.0


def add_live_arguments(parser: argparse.ArgumentParser) -> None:
    """``--foxglove [HOST:]PORT``, ``--foxglove-image-hz``, ``--foxglove-mcap``."""
    g = parser.add_argument_group("Foxglove live view (extra air-sitl[foxglove])")
    g.add_argument(
        "--foxglove",
        nargs="?",
        const=f"{DEFAULT_HOST}:{DEFAULT_PORT}",
        default=None,
        metavar="[HOST:]PORT",
        help=f"serve the flight to Foxglove (default {DEFAULT_HOST}:{DEFAULT_PORT}, "
        "--instance N adds N; port 0: any free port, printed)",
    )
    g.add_argument(
        "--foxglove-image-hz",
        type=float,
        default=DEFAULT_IMAGE_HZ,
        metavar="HZ",
        help="camera images sent to Foxglove per second of simulation "
        f"(default {DEFAULT_IMAGE_HZ:g}; 0: none, and serve renders no camera for the view)",
    )
    g.add_argument(
        "--foxglove-mcap",
        metavar="FILE",
        default=None,
        help="record the Foxglove topics into this MCAP file while flying",
    )


def parse_endpoint(text: str, instance: int) -> tuple[str, int]:
    """``[HOST:]PORT`` (port + ``instance`` unless 0); OptionError naming the value."""
    host, _, port_text = text.rpartition(":")
    host = host or DEFAULT_HOST
    try:
        port = int(port_text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535 or not host:
        msg = f"--foxglove: {text!r} is not [HOST:]PORT (e.g. {DEFAULT_HOST}:{DEFAULT_PORT})"
        raise OptionError(msg)
    if port and instance:
        port += instance
        if port > 65535:
            msg = f"--foxglove: port {port} (with --instance {instance}) is above 65535"
            raise OptionError(msg)
    return host, port


def open_live(
    args: argparse.Namespace, *, vehicle: str, home: GeoPoint | None, camera: CameraModel | None
) -> FoxgloveLive | None:
    """The live view the options ask for (None without ``--foxglove``/``--foxglove-mcap``)."""
    if args.foxglove is None and args.foxglove_mcap is None:
        return None
    option = "--foxglove" if args.foxglove is not None else "--foxglove-mcap"
    if not args.foxglove_image_hz >= 0:
        msg = f"--foxglove-image-hz: {args.foxglove_image_hz:g} (must be 0 or more)"
        raise OptionError(msg)
    require_sdk(option)
    from air_sitl.foxglove.live import FoxgloveLive, LiveOptions

    instance = int(getattr(args, "instance", None) or 0)
    host, port = DEFAULT_HOST, None
    if args.foxglove is not None:
        host, port = parse_endpoint(args.foxglove, instance)
    options = LiveOptions(
        host=host,
        port=port,
        image_hz=float(args.foxglove_image_hz),
        mcap=None if args.foxglove_mcap is None else Path(args.foxglove_mcap),
    )
    return FoxgloveLive(options, vehicle=vehicle, home=home, camera=camera)


def attach_live(
    live: FoxgloveLive | None,
    mission: Mission,
    hookup: BusHookup | None,
    endpoint: VehicleEndpoint | None = None,
) -> None:
    """Once the flight is assembled: the mission as flown, the bus's estimates and (serve)
    the STATUSTEXT the vehicle sends and each mission a client uploads."""
    if live is None:
        return
    live.start(mission)
    if hookup is not None and hookup.log is not None:
        hookup.log.listeners.append(live.on_estimate)
    if endpoint is not None:
        endpoint.text_listeners.append(live.on_statustext)
        endpoint.mission_listeners.append(live.start)
