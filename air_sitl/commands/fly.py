"""``air-sitl fly PLAN``: fly a mission plan to its end and record it."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

HELP = "fly a QGC mission plan (.plan or QGC WPL) to its end and record trajectory, summary and frames"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``fly``."""
    from air_sitl.options import add_flight_arguments

    parser.add_argument("plan", metavar="PLAN", help="QGroundControl .plan file or QGC WPL 110 text")
    parser.add_argument(
        "--out", default=None, help="output folder (created; refused if not empty). Default: out/<plan>"
    )
    parser.add_argument("--no-camera", action="store_true", help="do not render camera frames")
    parser.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    add_flight_arguments(parser, default_speed=0.0)


def prepare_out_dir(path: Path) -> Path:
    """Create ``path``; refuse an existing non-empty folder or a file in the way."""
    from air_sitl.errors import DatasetError

    if path.exists():
        if not path.is_dir():
            msg = f"{path}: exists and is not a folder"
            raise DatasetError(msg)
        if any(path.iterdir()):
            msg = f"{path}: folder exists and is not empty (choose another --out)"
            raise DatasetError(msg)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"{path}: cannot create the output folder: {err.strerror}"
        raise DatasetError(msg) from None
    return path


def write_json(path: Path, content: dict[str, Any]) -> None:
    """Write JSON atomically (temporary name, then rename)."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(content, indent=2, sort_keys=True) + "\n", encoding="utf-8")
    tmp.replace(path)


def run(args: argparse.Namespace) -> int:
    """Fly the plan; exit 0 when the mission completed, 1 when it did not."""
    from air_sitl.flightlog import TrajectoryWriter
    from air_sitl.mission.plan_file import load_mission
    from air_sitl.options import flight_options_from_args
    from air_sitl.progress import ProgressBar, print_summary
    from air_sitl.runner import assemble_flight

    options = flight_options_from_args(args)
    mission = load_mission(Path(args.plan))
    out = prepare_out_dir(Path(args.out) if args.out else Path("out") / (mission.name or "flight"))
    sinks = [TrajectoryWriter(out / "trajectory.csv")]
    flight, _home, _initial = assemble_flight(mission, options, sinks=sinks)
    show = not args.quiet and sys.stderr.isatty()
    bar = ProgressBar(mission, sys.stderr) if show else None
    result = flight.run(
        stop=lambda sample: sample.autopilot.mission_completed,
        max_sim_time_ns=int(options.max_sim_time_s * 1e9),
        progress=bar.update if bar else None,
    )
    if bar:
        bar.finish()
    summary = dict(result.summary)
    summary["plan"] = str(args.plan)
    write_json(out / "summary.json", summary)
    if not args.quiet:
        print_summary(summary, out, sys.stdout)
    return 0 if result.mission_completed else 1
