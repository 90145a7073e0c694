"""``air-sitl dataset``: fly AIR's scenarios from ``missions/`` into ``ROOT/<scenario>/``.

Each scenario is one ``fly`` recording (camera, dataset writer, manifest). ``-j N`` runs N
scenarios at once in separate processes. Prints one progress line per scenario and an overall
one, then the AIR table beside the paper's figures, also written as ``ROOT/stats.csv``.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import os
import sys
import time
from pathlib import Path

from air_sitl.builder import load_setup, open_setup_map
from air_sitl.camera.options import add_camera_arguments, camera_from_args, close_map
from air_sitl.dataset.scenarios import (
    PAPER_TABLE,
    ScenarioStats,
    format_table,
    missions_dir,
    parse_scenarios,
    stats_table,
)
from air_sitl.errors import DatasetError, OptionError
from air_sitl.files import require_writable_folder, write_bytes_atomic
from air_sitl.options import MapChoice, add_flight_arguments, flight_options_from_args, int_in_range
from air_sitl.progress import JobsDisplay
from air_sitl.recording.batch import Job, run_jobs

HELP = "fly the AIR scenarios (all 12 or a list) into ROOT/<scenario>/ and print the AIR table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``dataset``."""
    parser.add_argument(
        "--scenarios", default="all", help="'all' (default) or names such as FL-200,UC-300"
    )
    parser.add_argument("--out", default="out/air", metavar="ROOT", help="default out/air")
    parser.add_argument(
        "-j", "--jobs", default="1", metavar="N", help="scenarios flown at once (processes)"
    )
    parser.add_argument("--missions", default=None, metavar="DIR", help="folder of the plans")
    parser.add_argument("--map-urban", default=None, metavar="PATH", help="GeoTIFF for U*")
    parser.add_argument("--map-forest", default=None, metavar="PATH", help="GeoTIFF for F*")
    parser.add_argument("--map-seed", type=int, default=0, metavar="N")
    parser.add_argument(
        "--dem",
        default=None,
        metavar="FILE",
        help="relief: a GeoTIFF elevation model (AMSL) or builtin (the procedural maps' own)",
    )
    parser.add_argument(
        "--dates",
        default=None,
        metavar="D1,D2,...",
        help="map dates to fly each scenario over (default: the first date); with several, "
        "folders are ROOT/<scenario>@<date>/",
    )
    parser.add_argument("--zip", action="store_true", help="also pack each folder as ROOT/<n>.zip")
    parser.add_argument(
        "--resume", action="store_true", help="continue unfinished folders, skip complete ones"
    )
    parser.add_argument("--quiet", action="store_true", help="only the final table")
    add_flight_arguments(parser, default_speed=0.0)
    add_camera_arguments(parser)


def build_jobs(args: argparse.Namespace) -> list[Job]:
    """Validate the options, load the plans and list the jobs (errors before anything flies)."""
    options = flight_options_from_args(args)
    camera = camera_from_args(args)
    int_in_range("-j", args.jobs, 1, 64)  # validated before anything flies
    folder = missions_dir(args.missions)
    names = parse_scenarios(args.scenarios, folder)
    dates: list[str | None] = [None]
    if args.dates:
        dates = [d.strip() for d in args.dates.split(",") if d.strip()] or [None]
    for path in (args.map_urban, args.map_forest):
        if path and not Path(path).is_file():
            msg = f"{path}: no such GeoTIFF"
            raise OptionError(msg)
    root = Path(args.out)
    # Every process may use every core: while one flies its take-off (physics only) the
    # other's renderers take the idle core.
    workers = max(1, min(4, os.cpu_count() or 2))
    jobs: list[Job] = []
    for scenario in names:
        spec = None
        if scenario.upper().startswith("U") and args.map_urban:
            spec = args.map_urban
        elif scenario.upper().startswith("F") and args.map_forest:
            spec = args.map_forest
        setup = load_setup(
            folder / f"{scenario}.plan",
            options,
            camera=camera,
            render_workers=workers,
            name=scenario,
        )
        for date in dates:
            name = scenario if len(dates) == 1 else f"{scenario}@{date}"
            out = root / name
            if out.exists() and not out.is_dir():
                msg = f"{out}: exists and is not a folder (remove it, or choose another --out)"
                raise DatasetError(msg)
            if out.exists() and any(out.iterdir()) and not args.resume:
                msg = f"{out}: folder exists and is not empty (choose another --out, or --resume)"
                raise DatasetError(msg)
            choice = MapChoice(spec=spec, seed=args.map_seed, date=date, dem=args.dem)
            jobs.append(
                Job(
                    name=name,
                    setup=dataclasses.replace(setup, map=choice),
                    out=out,
                    resume=bool(args.resume),
                    zip=bool(args.zip),
                )
            )
    for job in jobs:
        if job.setup.map.spec is not None:
            # A GeoTIFF map missing home fails now, not in an hour.
            close_map(open_setup_map(job.setup))
    return jobs


def run(args: argparse.Namespace) -> int:
    """Fly every job; exit 0 when all completed, 1 when a mission did not, 2 on errors."""
    jobs = build_jobs(args)
    root = Path(args.out)
    require_writable_folder(root, "output folder")  # found before anything flies
    n = min(int_in_range("-j", args.jobs, 1, 64), len(jobs))
    expected = {j.name: PAPER_TABLE.get(j.setup.name.upper(), (0, 0))[0] for j in jobs}
    stream = sys.stderr
    display = JobsDisplay([j.name for j in jobs], expected, stream, tty=stream.isatty())
    if args.quiet:
        display.tty = False
        display.stream = open(os.devnull, "w")  # noqa: SIM115  (closed below)
    start = time.monotonic()
    try:
        # Longest first (the paper's image counts): the processes finish together.
        outcomes = run_jobs(
            jobs,
            n,
            on_progress=display.update,
            on_done=display.done,
            first=lambda j: -expected[j.name],
        )
    finally:
        if args.quiet:
            display.stream.close()
    wall = time.monotonic() - start
    stats = [
        ScenarioStats(
            scenario=o.name,
            images=o.images,
            distance_m=o.distance_m,
            mission_completed=o.mission_completed,
            sim_time_s=o.sim_time_s,
        )
        for o in outcomes
        if o.error is None
    ]
    table = ""
    table_error = ""
    if stats:
        rows = stats_table(stats)
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows(rows)
        sys.stdout.write(format_table(rows) + "\n")
        try:
            write_bytes_atomic(root / "stats.csv", text.getvalue().encode("ascii"))
            table = f"; table in {root / 'stats.csv'}"
        except OSError as err:
            table_error = f"{root / 'stats.csv'}: cannot write the table: {err.strerror}"
    frames = sum(o.images for o in outcomes)
    sys.stdout.write(
        f"{len(stats)}/{len(outcomes)} scenarios, {frames} frames in {wall:.0f} s wall "
        f"({frames / wall if wall > 0 else 0:.0f} frames/s){table}\n"
    )
    errors = [o for o in outcomes if o.error]
    for o in errors:
        sys.stderr.write(f"air-sitl: error: {o.name}: {o.error}\n")
    if table_error:
        sys.stderr.write(f"air-sitl: error: {table_error}\n")
        return 2
    if errors:
        return 2
    return 0 if all(o.mission_completed for o in outcomes) else 1
