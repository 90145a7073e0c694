"""``air-sitl dataset``: fly the scenarios from ``missions/`` into ``ROOT/<scenario>/``.

``--scenarios all`` flies AIR's 12 and the 6 farmland ones (``air`` or ``farmland`` alone);
the table compares AIR's rows with the paper, the farmland rows follow with their own total.

Each scenario is one ``fly`` recording (camera, dataset writer, manifest). ``-j N`` runs N
scenarios at once in separate processes. Says first how much disk the recordings will take
(and refuses when the file system has less free, unless ``--ignore-free-space``), shows a
progress bar per scenario and an overall one (frames, frames/s, ETA; plain lines every 10 % or
30 s when stderr is not a terminal), then the AIR table beside the paper's figures, also
written as ``ROOT/stats.csv``.
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
from typing import TYPE_CHECKING

from air_sitl.camera.options import add_camera_arguments, camera_from_args
from air_sitl.errors import DatasetError, OptionError
from air_sitl.options import MapChoice, add_flight_arguments, flight_options_from_args, int_in_range
from air_sitl.outdir import add_out_arguments

if TYPE_CHECKING:  # the flights' modules load when they fly, not for --help
    from air_sitl.recording.batch import Job

HELP = "fly the scenarios (AIR's 12 and farmland's 6, or a list) into ROOT/<scenario>/: AIR table"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``dataset``."""
    parser.add_argument(
        "--scenarios",
        default="all",
        help="'all' (default: AIR's 12 and the 6 farmland ones), 'air', 'farmland' or names "
        "such as FL-200,UC-300,AC-200",
    )
    parser.add_argument("--out", default="out/air", metavar="ROOT", help="default out/air")
    parser.add_argument(
        "-j", "--jobs", default="1", metavar="N", help="scenarios flown at once (processes)"
    )
    parser.add_argument("--missions", default=None, metavar="DIR", help="folder of the plans")
    parser.add_argument("--map-urban", default=None, metavar="PATH", help="GeoTIFF for U*")
    parser.add_argument("--map-forest", default=None, metavar="PATH", help="GeoTIFF for F*")
    parser.add_argument("--map-farmland", default=None, metavar="PATH", help="GeoTIFF for A*")
    parser.add_argument(
        "--map",
        default=None,
        metavar="MAP",
        help="map of every other scenario: a GeoTIFF, dates a.tif,b.tif, a folder of dated "
        "GeoTIFFs (map fetch's) or a procedural map (default: by the plan name)",
    )
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
    add_out_arguments(parser, resume="continue unfinished folders, skip complete ones")
    parser.add_argument(
        "--ignore-free-space",
        action="store_true",
        help="fly even when the file system of ROOT has less free space than the estimate",
    )
    parser.add_argument("--quiet", action="store_true", help="only the final table")
    add_flight_arguments(parser, default_speed=0.0)
    add_camera_arguments(parser)


def build_jobs(args: argparse.Namespace) -> list[Job]:
    """Validate the options, load the plans and list the jobs (errors before anything flies)."""
    from air_sitl.builder import load_setup, open_setup_map
    from air_sitl.dataset.scenarios import missions_dir, parse_scenarios
    from air_sitl.maps.choose import close_map
    from air_sitl.recording.batch import Job

    options = flight_options_from_args(args)
    camera = camera_from_args(args)
    int_in_range("-j", args.jobs, 1, 64)  # validated before anything flies
    folder = missions_dir(args.missions)
    names = parse_scenarios(args.scenarios, folder)
    dates: list[str | None] = [None]
    if args.dates:
        dates = [d.strip() for d in args.dates.split(",") if d.strip()] or [None]
    for path in (args.map_urban, args.map_forest, args.map_farmland):
        if path and not Path(path).is_file():
            msg = f"{path}: no such GeoTIFF"
            raise OptionError(msg)
    root = Path(args.out)
    # Every process may use every core: while one flies its take-off (physics only) the
    # other's renderers take the idle core.
    workers = max(1, min(4, os.cpu_count() or 2))
    jobs: list[Job] = []
    for scenario in names:
        spec = getattr(args, "map", None)
        if scenario.upper().startswith("U") and args.map_urban:
            spec = args.map_urban
        elif scenario.upper().startswith("F") and args.map_forest:
            spec = args.map_forest
        elif scenario.upper().startswith("A") and args.map_farmland:
            spec = args.map_farmland
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
        if not args.overwrite:
            _claim_job_folder(job, resume=bool(args.resume))
    return jobs


def _claim_job_folder(job: Job, *, resume: bool) -> None:
    """The rule of :mod:`air_sitl.outdir` for one scenario's folder, before anything flies:
    a non-empty one is refused, or continued with ``--resume`` when its inputs are the same
    (``--overwrite`` empties ROOT as a whole instead)."""
    from air_sitl.outdir import is_nonempty_folder, refusal
    from air_sitl.recording import folder_problem

    if not is_nonempty_folder(job.out):
        return
    problem = folder_problem(job.setup, job.out)
    if not resume:
        raise DatasetError(refusal(job.out, problem, resumable=True))
    if problem is not None:
        msg = f"{job.out}: --resume: {problem}; --overwrite replaces ROOT, or another --out"
        raise DatasetError(msg)


def run(args: argparse.Namespace) -> int:
    """Fly every job; exit 0 when all completed, 1 when a mission did not, 2 on errors."""
    from air_sitl.dataset.scenarios import (
        ScenarioStats,
        format_table,
        read_stats,
        stats_table,
    )
    from air_sitl.files import require_writable_folder, write_bytes_atomic
    from air_sitl.maps.procedural.shared_tiles import shared_folder
    from air_sitl.progress import JobsProgress
    from air_sitl.recording.batch import Outcome, run_jobs

    jobs = build_jobs(args)
    root = Path(args.out)
    expected = {j.name: forecast_frames(j) for j in jobs}
    # A read-only disk, then too little room: refused before anything flies or is made.
    require_writable_folder(root, "output folder", create=False)
    already = check_disk(jobs, expected, root, args)
    if args.overwrite:
        from air_sitl.outdir import claim_folder

        claim_folder(root, overwrite=True)
    # Scenarios flown into ROOT before, not by this run: their rows stay in the table.
    earlier = [
        s
        for s in read_stats(root / "stats.csv")
        if s.scenario not in {j.name for j in jobs} and (root / s.scenario).is_dir()
    ]
    n = min(int_in_range("-j", args.jobs, 1, 64), len(jobs))
    from air_sitl.dataset.size import frames_on_disk

    resumed = {j.name: frames_on_disk(j.out) for j in jobs} if args.resume else {}
    display = JobsProgress(
        [j.name for j in jobs],
        expected,
        enabled=not args.quiet,
        already=already,
        resumed=resumed,
    )

    def on_progress(name: str, frames: int, sim_s: float) -> None:
        display.update(name, frames, f"sim {sim_s:.0f} s")

    def on_done(o: Outcome) -> None:
        if o.error:
            line = f"FAILED: {o.error}"
        else:
            ok = "done" if o.mission_completed else "done (mission NOT completed)"
            line = f"{ok}, {o.distance_m:.0f} m, {o.sim_time_s:.0f} s simulated"
        display.done(o.name, o.images, line)

    start = time.monotonic()
    try:
        # The scenarios of one area fly over the same ground: drawn once for all processes.
        with shared_folder() as shared:
            # Longest first (the paper's image counts): the processes finish together.
            outcomes = run_jobs(
                share_ground(jobs, shared),
                n,
                on_progress=on_progress,
                on_done=on_done,
                first=lambda j: -expected[j.name],
            )
    finally:
        display.close()
    wall = time.monotonic() - start
    stats = earlier + [
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
        f"{len(stats) - len(earlier)}/{len(outcomes)} scenarios, {frames} frames in "
        f"{wall:.0f} s wall "
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


def share_ground(jobs: list[Job], folder: Path) -> list[Job]:
    """The jobs with their procedural maps sharing the drawn ground through ``folder``
    (:mod:`air_sitl.maps.procedural.shared_tiles`: the same pixels, drawn once)."""
    return [
        dataclasses.replace(
            j,
            setup=dataclasses.replace(
                j.setup, map=dataclasses.replace(j.setup.map, shared_dir=folder)
            ),
        )
        for j in jobs
    ]


def forecast_frames(job: Job) -> int:
    """The frames ``job`` will capture, from its plan (:mod:`air_sitl.mission.forecast`: the
    legs at the plan's speed, cut by ``--max-sim-time``)."""
    from air_sitl.mission.forecast import capture_forecast

    options = job.setup.options
    forecast = capture_forecast(
        job.setup.mission,
        job.setup.home,
        air_start=options.air_start,
        max_sim_time_s=options.max_sim_time_s,
    )
    return forecast.frames


def check_disk(
    jobs: list[Job], expected: dict[str, int], root: Path, args: argparse.Namespace
) -> dict[str, int]:
    """Say how much the recordings will write; DatasetError when ROOT's file system has less
    free space (unless ``--ignore-free-space``). Estimated from the plans' frame forecasts and
    the JPEG quality (:mod:`air_sitl.dataset.size`), twice with ``--zip``; a resumed folder
    counts only what is missing, a complete one nothing. Returns the frames of the complete
    ones (``--resume``)."""
    from air_sitl.dataset.size import (
        complete_frames,
        frames_on_disk,
        free_bytes,
        human_bytes,
        recording_bytes,
    )

    total = 0
    frames = 0
    unknown = []
    complete = {}
    for job in jobs:
        camera = job.setup.camera
        if args.resume and (done := complete_frames(job.out)) is not None:
            complete[job.name] = done
            continue
        if camera is None:
            unknown.append(job.name)
            continue
        missing = expected[job.name] - (frames_on_disk(job.out) if args.resume else 0)
        frames += max(0, missing)
        size = recording_bytes(
            max(0, missing), camera.jpeg_quality, camera.width_px, camera.height_px
        )
        # --zip packs each folder beside it (stored, not compressed: JPEGs do not shrink).
        total += 2 * size if args.zip else size
    free = free_bytes(root)
    quality = jobs[0].setup.camera.jpeg_quality if jobs and jobs[0].setup.camera else None
    note = f" (and {', '.join(unknown)} of unknown size)" if unknown else ""
    kept = f" ({len(complete)} complete already)" if complete else ""
    zipped = ", folders and zips" if args.zip else ""
    if not args.quiet:
        print(
            f"dataset: {len(jobs)} recording{'' if len(jobs) == 1 else 's'}{kept}, about "
            f"{frames} frames to write: about {human_bytes(total)}{zipped} "
            f"into {root} at JPEG quality {quality}{note}; {human_bytes(free)} free there",
            file=sys.stderr,
            flush=True,
        )
    if total > free and not args.ignore_free_space:
        msg = (
            f"{root}: the recordings need about {human_bytes(total)}, the file system has "
            f"{human_bytes(free)} free (--ignore-free-space to fly anyway)"
        )
        raise DatasetError(msg)
    return complete
