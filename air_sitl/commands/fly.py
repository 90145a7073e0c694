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

from air_sitl.builder import load_setup
from air_sitl.bus.hookup import bus_sinks_from_args
from air_sitl.camera.options import camera_from_args, map_choice_from_args
from air_sitl.commands.flying import add_vehicle_arguments
from air_sitl.mission.items import Mission
from air_sitl.mission.validate import mission_warnings, require_startable
from air_sitl.options import flight_options_from_args, int_in_range
from air_sitl.progress import ProgressBar, print_summary
from air_sitl.recording import RecordingRequest, record_flight
from air_sitl.runner import Flight
from air_sitl.state import SimSample

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
        help="output folder (created; refused if not empty). Default: out/<plan>",
    )
    parser.add_argument("--no-camera", action="store_true", help="do not render camera frames")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an unfinished recording in --out (same plan and options) from its last "
        "whole frame; the result is byte-identical to an uninterrupted run",
    )
    parser.add_argument(
        "--render-workers",
        default="2",
        metavar="N",
        help="camera rendering threads (default 2; 0 renders on the simulation thread)",
    )
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_vehicle_arguments(parser, default_speed=0.0)


def run(args: argparse.Namespace) -> int:
    """Fly the plan; exit 0 when the mission completed, 1 when it did not."""
    setup = load_setup(
        Path(args.plan),
        flight_options_from_args(args),
        camera=None if args.no_camera else camera_from_args(args),
        map=map_choice_from_args(args),
        render_workers=int_in_range("--render-workers", args.render_workers, 0, 64),
    )
    require_startable(setup.mission)  # PX4 would refuse to start it: so do we
    out = Path(args.out) if args.out else Path("out") / (setup.mission.name or "flight")
    request = RecordingRequest(
        setup=setup, out=out, resume=bool(args.resume), bus=bus_sinks_from_args(args)
    )
    show = not args.quiet and sys.stderr.isatty()
    bars: list[ProgressBar] = []

    def on_start(mission: Mission, first_frame: int) -> None:
        if not args.quiet:
            for warning in mission_warnings(mission):
                print(f"{mission.source}: warning: {warning}", file=sys.stderr)
        if show:
            bars.append(ProgressBar(mission, sys.stderr))
        if first_frame and not args.quiet:
            print(f"resuming {out} from frame {first_frame}", file=sys.stderr)

    def progress(sample: SimSample, flight: Flight) -> None:
        if bars:
            bars[0].update(sample, flight)

    with request.bus or contextlib.nullcontext():
        result = record_flight(request, progress=progress, on_start=on_start)
    if bars:
        bars[0].finish()
    if result.already_complete:
        if not args.quiet:
            print(f"{out}: already complete ({result.resumed_from_frame} frames); nothing to do")
        return 0
    if not args.quiet:
        print_summary(result.summary, out, sys.stdout)
        if result.manifest is not None:
            print(
                f"  archive          {result.manifest.get('frame_count')} frames, manifest written"
            )
    return 0 if result.mission_completed else 1
