"""``air-sitl dataset``: fly AIR's scenarios from ``missions/`` into ``ROOT/<scenario>/``.

Each scenario is one ``fly`` recording (camera, dataset writer, manifest). ``-j N`` runs N
scenarios at once in separate processes. Prints one progress line per scenario and an overall
one, then the AIR table beside the paper's figures, also written as ``ROOT/stats.csv``.
"""

from __future__ import annotations

import argparse
import csv
import ctypes
import ctypes.util
import dataclasses
import io
import multiprocessing
import os
import queue
import signal
import sys
import time
import zipfile
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from air_sitl.builder import FlightSetup, load_setup, open_setup_map
from air_sitl.camera.options import add_camera_arguments, camera_from_args, close_map
from air_sitl.dataset.scenarios import (
    PAPER_TABLE,
    ScenarioStats,
    format_table,
    missions_dir,
    parse_scenarios,
    stats_table,
)
from air_sitl.errors import AirSitlError, DatasetError, OptionError
from air_sitl.files import write_bytes_atomic
from air_sitl.options import MapChoice, add_flight_arguments, flight_options_from_args, int_in_range
from air_sitl.recording import RecordingRequest, record_flight
from air_sitl.runner import Flight
from air_sitl.state import SimSample

HELP = "fly the AIR scenarios (all 12 or a list) into ROOT/<scenario>/ and print the AIR table"

_PROGRESS: Any = None  # the workers' progress queue (set by the pool initializer)


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


@dataclass(frozen=True, slots=True, kw_only=True)
class Job:
    """One scenario at one map date."""

    name: str  # folder name: scenario, or scenario@date
    setup: FlightSetup
    out: Path
    resume: bool
    zip: bool


@dataclass(frozen=True, slots=True, kw_only=True)
class Outcome:
    """How one job ended: its stats, or a one-line error."""

    name: str
    images: int = 0
    distance_m: float = 0.0
    mission_completed: bool = False
    sim_time_s: float = 0.0
    wall_s: float = 0.0
    error: str | None = None


def _init_worker(progress: Any) -> None:
    global _PROGRESS  # noqa: PLW0603  (one queue per worker process)
    _PROGRESS = progress
    _die_with_parent()


def _die_with_parent() -> None:
    """Linux: a worker gets SIGKILL when the parent dies (a killed ``dataset`` leaves no
    orphan still writing into a folder that ``--resume`` is about to continue)."""
    pr_set_pdeathsig = 1
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        libc.prctl(pr_set_pdeathsig, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):
        pass


def zip_folder(folder: Path, out: Path) -> None:
    """Pack ``folder`` as ``out`` (stored, fixed timestamps: the same bytes every time)."""
    tmp = out.with_name(out.name + ".tmp")
    files = sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith("."))
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
        for path in files:
            info = zipfile.ZipInfo(
                f"{folder.name}/{path.relative_to(folder).as_posix()}", (1980, 1, 1, 0, 0, 0)
            )
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_STORED
            with path.open("rb") as src, zf.open(info, "w") as dst:
                while block := src.read(1 << 20):
                    dst.write(block)
    tmp.replace(out)


def run_job(job: Job, progress: Any = None) -> Outcome:
    """Fly one job (in a worker process or inline); errors come back as one line."""
    sink = progress if progress is not None else _PROGRESS
    start = time.monotonic()

    def report(sample: SimSample, flight: Flight) -> None:
        if sink is not None:
            sink.put((job.name, flight.stats.capture_frames, sample.state.sim_time_ns / 1e9))

    try:
        result = record_flight(
            RecordingRequest(setup=job.setup, out=job.out, resume=job.resume),
            progress=report,
        )
        if job.zip:
            zip_folder(job.out, job.out.with_name(job.out.name + ".zip"))
    except AirSitlError as err:
        return Outcome(name=job.name, error=str(err), wall_s=time.monotonic() - start)
    except OSError as err:
        return Outcome(name=job.name, error=f"{job.out}: {err}", wall_s=time.monotonic() - start)
    manifest = result.manifest or {}
    summary = result.summary
    return Outcome(
        name=job.name,
        images=int(manifest.get("frame_count", summary.get("capture_frames", 0))),
        distance_m=float(summary.get("capture_distance_m") or 0.0),
        mission_completed=result.mission_completed,
        sim_time_s=float(summary.get("sim_time_s") or 0.0),
        wall_s=time.monotonic() - start,
    )


class Display:
    """One progress line per job plus an overall one (redrawn in place on a terminal)."""

    def __init__(self, names: list[str], expected: dict[str, int], stream: IO[str], tty: bool):
        self.names = names
        self.expected = expected
        self.stream = stream
        self.tty = tty
        self.frames = dict.fromkeys(names, 0)
        self.sim_s = dict.fromkeys(names, 0.0)
        self.state = dict.fromkeys(names, "waiting")
        self.start = time.monotonic()
        self._drawn = 0
        self._last = 0.0

    def _bar(self, done: int, total: int, width: int = 24) -> str:
        frac = min(1.0, done / total) if total > 0 else 0.0
        filled = int(frac * width)
        return f"[{'#' * filled}{'.' * (width - filled)}] {100 * frac:5.1f}%"

    def update(self, name: str, frames: int, sim_s: float) -> None:
        """A progress report from a job."""
        if self.state[name] == "waiting":
            self.state[name] = "flying"
            if not self.tty:
                self.stream.write(f"{name}: flying\n")
        self.frames[name] = frames
        self.sim_s[name] = sim_s
        self.draw()

    def done(self, outcome: Outcome) -> None:
        """A job finished."""
        name = outcome.name
        if outcome.error:
            self.state[name] = "FAILED"
            line = f"{name}: FAILED: {outcome.error}"
        else:
            self.frames[name] = outcome.images
            ok = "done" if outcome.mission_completed else "done (mission NOT completed)"
            self.state[name] = ok
            line = (
                f"{name}: {ok}: {outcome.images} frames, {outcome.distance_m:.0f} m, "
                f"{outcome.sim_time_s:.0f} s simulated in {outcome.wall_s:.0f} s"
            )
        if not self.tty:
            finished = sum(1 for s in self.state.values() if s not in ("waiting", "flying"))
            self.stream.write(f"[{finished}/{len(self.names)}] {line}\n")
            self.stream.flush()
        self.draw(force=True)

    def draw(self, *, force: bool = False) -> None:
        """Redraw every line (terminal only, at most 10 times a second)."""
        if not self.tty:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        lines = []
        for name in self.names:
            lines.append(
                f"{name:>16} {self._bar(self.frames[name], self.expected.get(name, 0))} "
                f"{self.frames[name]:6d} frames  sim {self.sim_s[name]:6.0f} s  {self.state[name]}"
            )
        total = sum(self.frames.values())
        total_expected = sum(self.expected.get(n, 0) for n in self.names)
        wall = now - self.start
        lines.append(
            f"{'overall':>16} {self._bar(total, total_expected)} {total:6d} frames  "
            f"{wall:6.0f} s wall  {total / wall if wall > 0 else 0:5.0f} frames/s"
        )
        if self._drawn:
            self.stream.write(f"\x1b[{self._drawn}F")
        self.stream.write("\n".join(f"{line}\x1b[K" for line in lines) + "\n")
        self.stream.flush()
        self._drawn = len(lines)


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
            if out.exists() and any(out.iterdir()) and not args.resume:
                msg = f"{out}: folder exists and is not empty (choose another --out, or --resume)"
                raise DatasetError(msg)
            choice = MapChoice(spec=spec, seed=args.map_seed, date=date)
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


def _run_pool(jobs: list[Job], n: int, display: Display) -> list[Outcome]:
    # Spawned, not forked: a fork copies the parent's threads' locks (OpenCV's thread pool,
    # zenoh) in whatever state they are, and a worker can hang on one; a caller that had
    # rendered in-process before running a pool hung this way.
    ctx = multiprocessing.get_context("spawn")
    progress = ctx.Queue()
    outcomes: dict[str, Outcome] = {}
    with ProcessPoolExecutor(
        max_workers=n, mp_context=ctx, initializer=_init_worker, initargs=(progress,)
    ) as pool:
        # Longest first (the paper's image counts): the processes finish together.
        order = sorted(jobs, key=lambda j: -PAPER_TABLE.get(j.setup.name.upper(), (0, 0))[0])
        futures: dict[Future[Outcome], Job] = {pool.submit(run_job, job): job for job in order}
        pending = set(futures)
        while pending:
            try:
                name, frames, sim_s = progress.get(timeout=0.2)
                display.update(name, frames, sim_s)
            except queue.Empty:
                pass
            for fut in [f for f in pending if f.done()]:
                pending.discard(fut)
                try:
                    outcome = fut.result()
                except Exception as err:  # a crashed worker: report it, keep the others
                    outcome = Outcome(name=futures[fut].name, error=f"worker failed: {err!r}")
                outcomes[outcome.name] = outcome
                display.done(outcome)
    return [outcomes[job.name] for job in jobs]


def run(args: argparse.Namespace) -> int:
    """Fly every job; exit 0 when all completed, 1 when a mission did not, 2 on errors."""
    jobs = build_jobs(args)
    root = Path(args.out)
    try:
        root.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        msg = f"{root}: cannot create the output folder: {err.strerror}"
        raise DatasetError(msg) from None
    n = min(int_in_range("-j", args.jobs, 1, 64), len(jobs))
    expected = {j.name: PAPER_TABLE.get(j.setup.name.upper(), (0, 0))[0] for j in jobs}
    stream = sys.stderr
    display = Display([j.name for j in jobs], expected, stream, tty=stream.isatty())
    if args.quiet:
        display.tty = False
        display.stream = open(os.devnull, "w")  # noqa: SIM115  (closed below)
    start = time.monotonic()
    try:
        if n <= 1:
            outcomes = []
            for job in jobs:
                outcome = run_job(job, progress=_DirectProgress(display))
                display.done(outcome)
                outcomes.append(outcome)
        else:
            outcomes = _run_pool(jobs, n, display)
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
    if stats:
        rows = stats_table(stats)
        text = io.StringIO()
        csv.writer(text, lineterminator="\n").writerows(rows)
        write_bytes_atomic(root / "stats.csv", text.getvalue().encode("ascii"))
        sys.stdout.write(format_table(rows) + "\n")
    frames = sum(o.images for o in outcomes)
    sys.stdout.write(
        f"{len(stats)}/{len(outcomes)} scenarios, {frames} frames in {wall:.0f} s wall "
        f"({frames / wall if wall > 0 else 0:.0f} frames/s); table in {root / 'stats.csv'}\n"
    )
    errors = [o for o in outcomes if o.error]
    for o in errors:
        sys.stderr.write(f"air-sitl: error: {o.name}: {o.error}\n")
    if errors:
        return 2
    return 0 if all(o.mission_completed for o in outcomes) else 1


class _DirectProgress:
    """The progress 'queue' of inline runs: updates the display at once."""

    def __init__(self, display: Display) -> None:
        self.display = display

    def put(self, item: tuple[str, int, float]) -> None:
        self.display.update(*item)
