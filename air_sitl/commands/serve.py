"""``air-sitl serve``: a PX4-like vehicle on MAVLink links, flown by ground stations.

Parses the options into a FlightSetup and serves it (:mod:`air_sitl.serving`) until SIGINT or
SIGTERM. The camera streams as RTP/H.264 (``--video``, :mod:`air_sitl.video`); ``--instance N``
numbers the vehicle as PX4 multi-vehicle SITL does (:mod:`air_sitl.instance`).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING

from air_sitl.bus.keys import DEFAULT_VEHICLE
from air_sitl.camera.options import camera_from_args, map_choice_from_args
from air_sitl.commands.flying import add_vehicle_arguments
from air_sitl.errors import OptionError
from air_sitl.foxglove.commands import add_live_arguments, attach_live, open_live
from air_sitl.instance import HOME_SPACING_M, Instance, add_instance_arguments, instance_from_args
from air_sitl.mavlink.links import parse_link
from air_sitl.options import OPEN_END_NS, FlightOptions, flight_options_from_args
from air_sitl.state import GeoPoint
from air_sitl.video.options import add_video_arguments, video_options_from_args

if TYPE_CHECKING:
    from air_sitl.builder import FlightSetup

HELP = "run a PX4-like MAVLink vehicle that ground stations connect to, upload missions to and fly"
DEFAULT_HOME = (47.397742, 8.545594, 488.0)  # PX4 SITL's default home (Zurich)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``serve``."""
    parser.add_argument(
        "--mavlink",
        action="append",
        metavar="URL",
        help="udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT; repeatable "
        "(default: udpout:127.0.0.1:14550 and udpout:127.0.0.1:14540+N, as PX4 SITL)",
    )
    parser.add_argument("--plan", default=None, help="preload this .plan as if uploaded")
    parser.add_argument(
        "--home", default=None, help="LAT,LON,ALT_AMSL (default: the plan's home, else PX4's)"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="record each capture window (camera frames, AIR archive) into OUT/<n>/",
    )
    parser.add_argument(
        "--signing-key", default=None, metavar="HEX|@FILE", help="MAVLink 2 signing key"
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    add_video_arguments(parser)
    add_instance_arguments(parser)
    add_live_arguments(parser)
    add_vehicle_arguments(parser, default_speed=1.0)
    # A vehicle serves until stopped: no time limit unless one is given.
    for action in parser._actions:
        if action.dest == "max_sim_time":
            action.default = None
            action.help = "stop after this many simulated seconds (default: run until stopped)"


def parse_home(text: str) -> GeoPoint:
    """``LAT,LON,ALT`` in degrees and metres AMSL."""
    parts = text.split(",")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        msg = f"--home {text!r}: expected LAT,LON,ALT_AMSL (for example 47.3977,8.5456,488)"
        raise OptionError(msg) from None
    if not (math.isfinite(lat + lon + alt) and -90 <= lat <= 90 and -180 <= lon <= 180):
        msg = f"--home {text!r}: latitude must be in [-90, 90], longitude in [-180, 180]"
        raise OptionError(msg)
    return GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted; exit 0 on SIGINT/SIGTERM."""
    from air_sitl.bus.hookup import bus_sinks_from_args
    from air_sitl.mavlink.codec import load_signing_key
    from air_sitl.serving import serve_vehicle

    limited = args.max_sim_time is not None
    if not limited:
        # The options keep their default; the served flight gets no limit (OPEN_END_NS).
        default = FlightOptions().max_sim_time_s
        args = argparse.Namespace(**{**vars(args), "max_sim_time": str(default)})
    options = flight_options_from_args(args)
    if options.air_start:
        msg = "--air-start: serve starts on the ground; upload, arm and start from a client"
        raise OptionError(msg)
    instance = instance_from_args(args)
    if args.instance is not None and args.vehicle == DEFAULT_VEHICLE:
        args.vehicle = instance.vehicle_name  # zenoh keys air/uavN/...
    video = video_options_from_args(args, default_port=instance.video_port)
    specs = [parse_link(url) for url in (args.mavlink or instance.links)]
    for spec in specs:
        if not spec.loopback:
            print(
                f"air-sitl serve: warning: {spec} is reachable from other machines",
                file=sys.stderr,
            )
    key = load_signing_key(args.signing_key) if args.signing_key else None
    setup = _setup(args, options, instance)
    if args.out:
        from air_sitl.files import require_writable_folder

        # Refused now, not after "Capture started" was told to the ground station.
        require_writable_folder(Path(args.out), "--out folder")
    live = open_live(args, vehicle=args.vehicle, home=setup.home, camera=setup.camera)
    stop = threading.Event()

    def on_signal(signum: int, _frame: FrameType | None) -> None:
        stop.set()

    previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        with bus_sinks_from_args(args) as hookup:
            c = serve_vehicle(
                setup,
                specs,
                stop=stop,
                max_sim_time_ns=_max_sim_ns(options.max_sim_time_s) if limited else OPEN_END_NS,
                bus=hookup,
                out=Path(args.out) if args.out else None,
                signing_key=key,
                quiet=bool(args.quiet),
                system_id=instance.system_id,
                video=video,
                home_note=_home_note(args, instance),
                view=live,
                view_image_hz=live.options.image_hz if live is not None else 0.0,
                on_attached=lambda bus, ep: attach_live(live, setup.mission, bus, ep),
            )
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        if live is not None:
            live.close()
    if not args.quiet:
        kernel = (
            f"{c.kernel_dropped} datagrams dropped by the kernel (socket buffer full)"
            if c.kernel_drops_counted or c.kernel_dropped
            else "kernel drops not counted (no UDP peer, or the platform does not tell)"
        )
        print(
            f"air-sitl serve: stopped; {c.messages} messages received, {c.dropped} frames "
            f"dropped ({c.parse_errors} parse errors, {c.unknown_ids} unknown, "
            f"{c.signature_rejected} signature rejected), {kernel}",
            flush=True,
        )
    return 0


def _max_sim_ns(max_sim_time_s: float) -> int:
    """The simulation time limit given with --max-sim-time, in nanoseconds."""
    return int(max_sim_time_s * 1e9)


def _home_note(args: argparse.Namespace, instance: Instance) -> str:
    """What the ready line says of a home no option gave: PX4 SITL's default (moved for
    instance N); nothing for a home of ``--home`` or of the plan."""
    if args.plan or args.home:
        return ""
    moved = f", {instance.number * HOME_SPACING_M:g} m east for instance {instance.number}"
    return f"no --plan or --home: PX4 SITL's default home, Zurich{moved if instance.number else ''}"


def _setup(args: argparse.Namespace, options: FlightOptions, instance: Instance) -> FlightSetup:
    """The served flight: the preloaded plan (or none) at ``--home``, else the plan's or PX4's
    moved by the instance's offset."""
    from air_sitl.builder import FlightSetup, home_on_terrain
    from air_sitl.mission.items import Mission
    from air_sitl.mission.plan_file import load_mission
    from air_sitl.runner import home_of

    if args.plan:
        mission = load_mission(Path(args.plan), terrain=args.dem is not None)
        for note in mission.notes:  # item warnings come as STATUSTEXT from the executor
            print(f"{mission.source}: warning: {note}", file=sys.stderr)
        home = parse_home(args.home) if args.home else instance.home(home_of(mission))
    else:
        mission = Mission(items=(), source="serve")
        lat, lon, alt = DEFAULT_HOME
        default = GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
        home = parse_home(args.home) if args.home else instance.home(default)
    setup = FlightSetup(
        mission=mission,
        home=home,
        name=mission.name,
        options=options,
        plan=Path(args.plan) if args.plan else None,
        camera=camera_from_args(args),
        map=map_choice_from_args(args),
    )
    return home_on_terrain(setup)  # with --dem the vehicle stands on the ground at home
