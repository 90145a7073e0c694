"""``air-sitl fly PLAN``: fly a mission plan to its end and record it.

With the camera (default) DIR becomes an AIR archive: JPEG frames of the capture window,
``metadata.csv``, ``frames.csv``, ``imu.csv``, ``camera.yaml``, the plan as flown,
``trajectory.csv``, ``summary.json`` and ``manifest.json`` (last). ``--no-camera`` writes only
``trajectory.csv`` and ``summary.json``. ``--resume`` continues a killed recording.
"""

from __future__ import annotations

import argparse
import contextlib
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.camera.options import camera_from_args, map_choice_from_args
from air_sitl.commands.flying import add_vehicle_arguments
from air_sitl.errors import MapError
from air_sitl.foxglove.commands import add_live_arguments, attach_live, open_live
from air_sitl.mission.geometry import POSITIONED_COMMANDS
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.mission.validate import mission_warnings, require_startable
from air_sitl.options import flight_options_from_args, int_in_range
from air_sitl.outdir import add_out_arguments
from air_sitl.state import GeoPoint, SimSample

if TYPE_CHECKING:  # the flight's modules load when it flies, not for --help
    from air_sitl.builder import FlightSetup
    from air_sitl.maps.base import MapSource
    from air_sitl.runner import Flight

HELP = (
    "fly a QGC mission plan (.plan or QGC WPL) to its end and record trajectory, summary and frames"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``fly``."""
    parser.add_argument(
        "plan", metavar="PLAN", help="QGroundControl .plan file or QGC WPL 110 text"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="output folder (created; a non-empty one is refused unless --resume or "
        "--overwrite). Default: out/<plan>",
    )
    parser.add_argument("--no-camera", action="store_true", help="do not render camera frames")
    add_out_arguments(
        parser,
        resume="continue an unfinished recording in --out (same plan and options) from its last "
        "whole frame; the result is byte-identical to an uninterrupted run",
    )
    parser.add_argument(
        "--render-workers",
        default="2",
        metavar="N",
        help="camera rendering threads (default 2; 0 renders on the simulation thread)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_live_arguments(parser)
    add_vehicle_arguments(parser, default_speed=0.0)


def plan_off_map(mission: Mission, home: GeoPoint, map_source: MapSource) -> str:
    """Why the plan leaves ``map_source`` (home or a positioned item outside it), or ''."""
    width, height = map_source.georef.width_px, map_source.georef.height_px
    if width is None or height is None:
        return ""  # an unbounded (procedural) map covers any flight
    points = [("home", home.lat_deg, home.lon_deg)]
    points += [
        (f"item {i}", item.lat_deg, item.lon_deg)
        for i, item in enumerate(mission.items)
        if item.command in POSITIONED_COMMANDS | {MavCmd.NAV_TAKEOFF, MavCmd.NAV_LAND}
        and not (item.lat_deg == 0.0 and item.lon_deg == 0.0)
    ]
    for where, lat, lon in points:
        x, y = map_source.latlon_to_map_px(lat, lon)
        if not (0.0 <= x < width and 0.0 <= y < height):
            return (
                f"{where} ({lat:.6f}, {lon:.6f}) is outside the map {map_source.name} "
                f"({width}x{height} px; at pixel {x:.0f}, {y:.0f}), expected a map covering "
                "the whole flight"
            )
    return ""


def require_on_map(setup: FlightSetup) -> None:
    """MapError when the plan leaves the flight's map (the same check with or without camera)."""
    from air_sitl.builder import open_setup_map
    from air_sitl.maps.choose import close_map

    map_source = open_setup_map(setup)
    try:
        problem = plan_off_map(setup.mission, setup.home, map_source)
    finally:
        close_map(map_source)
    if problem:
        msg = f"{setup.mission.source}: {problem}"
        raise MapError(msg)


def run(args: argparse.Namespace) -> int:
    """Fly the plan; exit 0 when the mission completed, 1 when it did not."""
    from air_sitl.builder import load_setup
    from air_sitl.bus.args import bus_options_from_args
    from air_sitl.progress import Progress, print_summary
    from air_sitl.recording import RecordingRequest, record_flight

    setup = load_setup(
        Path(args.plan),
        flight_options_from_args(args),
        camera=None if args.no_camera else camera_from_args(args),
        map=map_choice_from_args(args),
        render_workers=int_in_range("--render-workers", args.render_workers, 0, 64),
    )
    require_startable(setup.mission)  # PX4 would refuse to start it: so do we
    require_on_map(setup)  # with or without the camera: the flight is on its map
    out = Path(args.out) if args.out else Path("out") / (setup.mission.name or "flight")
    live = open_live(args, vehicle=args.vehicle, home=setup.home, camera=setup.camera)
    bus = None  # zenoh loads only when an option asks for the bus
    if bus_options_from_args(args).enabled:
        from air_sitl.bus.hookup import bus_sinks_from_args

        bus = bus_sinks_from_args(args)
    request = RecordingRequest(
        setup=setup,
        out=out,
        resume=bool(args.resume),
        overwrite=bool(args.overwrite),
        bus=bus,
        sinks=() if live is None else (live,),
    )
    bars: list[Progress] = []  # made when the flight starts (the mission as flown)

    def on_start(mission: Mission, first_frame: int) -> None:
        if not args.quiet:
            for warning in mission_warnings(mission):
                print(f"{mission.source}: warning: {warning}", file=sys.stderr)
        if first_frame and not args.quiet:
            print(f"resuming {out} from frame {first_frame}", file=sys.stderr)
        total = max(1, len(mission.items))
        bars.append(Progress(mission.name or "flight", total, unit="items", enabled=not args.quiet))
        attach_live(live, mission, request.bus)

    def progress(sample: SimSample, flight: Flight) -> None:
        if bars:
            seq = max(0, sample.autopilot.current_seq)
            note = f"sim {sample.state.sim_time_ns / 1e9:.0f} s, {sample.autopilot.mode.value}"
            if not args.no_camera:
                note += f", {flight.stats.capture_frames} frames"
            bars[0].update_to(min(seq, bars[0].total or seq), note)

    try:
        with request.bus or contextlib.nullcontext():
            result = record_flight(request, progress=progress, on_start=on_start)
        if bars and result.mission_completed:  # the last item done
            bars[0].update_to(bars[0].total or 0, bars[0].postfix)
    finally:
        for bar in bars:
            bar.close()
        if live is not None:
            live.close()
    if result.already_complete:
        if not args.quiet:
            print(f"{out}: already complete ({result.resumed_from_frame} frames); nothing to do")
        return 0
    if not args.quiet:
        print_summary(result.summary, out, sys.stdout, camera=not args.no_camera)
        if result.manifest is not None:
            print(
                f"  archive          {result.manifest.get('frame_count')} frames, manifest written"
            )
    return 0 if result.mission_completed else 1
