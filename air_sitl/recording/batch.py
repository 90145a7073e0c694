"""Many recordings at once: one job per scenario and map date, in worker processes or inline.

``run_jobs`` flies jobs in ``workers`` spawned processes (or inline with one), reports each
job's progress and outcome through callbacks, and returns the outcomes in the jobs' order.
A job's error comes back as one line in its outcome: the other jobs fly on.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import queue
import time
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from air_sitl.builder import FlightSetup
from air_sitl.errors import AirSitlError
from air_sitl.files import zip_folder
from air_sitl.recording.archive import RecordingRequest, RecordingResult, record_flight
from air_sitl.recording.dates import record_dates, shares_flight
from air_sitl.runner import Flight
from air_sitl.state import SimSample
from air_sitl.workers import die_with_parent

ReportFn = Callable[[str, int, float], None]  # (job name, capture frames, simulated s)

_PROGRESS: Any = None  # the workers' progress queue (set by the pool initializer)


@dataclass(frozen=True, slots=True, kw_only=True)
class Job:
    """One recording: a scenario at one map date."""

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
    die_with_parent()


def _report_to_parent(name: str, frames: int, sim_s: float) -> None:
    if _PROGRESS is not None:
        _PROGRESS.put((name, frames, sim_s))


def _run_in_worker(group: Sequence[Job]) -> list[Outcome]:
    return run_group(group, _report_to_parent)


def _outcome(job: Job, result: RecordingResult, start: float) -> Outcome:
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


def run_group(group: Sequence[Job], report_to: ReportFn | None = None) -> list[Outcome]:
    """Fly a group of jobs: once for all when they differ only in the map date (see
    :mod:`.dates`), else one after the other; errors come back as one line each."""
    requests = [RecordingRequest(setup=j.setup, out=j.out, resume=j.resume) for j in group]
    if not shares_flight(requests):
        return [run_job(job, report_to) for job in group]
    start = time.monotonic()

    def report(sample: SimSample, flight: Flight) -> None:
        if report_to is not None:
            for job in group:
                report_to(job.name, flight.stats.capture_frames, sample.state.sim_time_ns / 1e9)

    try:
        results = record_dates(requests, progress=report)
        for job in group:
            if job.zip:
                zip_folder(job.out, job.out.with_name(job.out.name + ".zip"))
    except AirSitlError as err:
        return [
            Outcome(name=j.name, error=str(err), wall_s=time.monotonic() - start) for j in group
        ]
    except OSError as err:
        wall = time.monotonic() - start
        return [Outcome(name=j.name, error=f"{j.out}: {err}", wall_s=wall) for j in group]
    return [_outcome(job, result, start) for job, result in zip(group, results, strict=True)]


def run_job(job: Job, report_to: ReportFn | None = None) -> Outcome:
    """Fly one job; errors come back as one line. ``report_to`` hears every simulated second."""
    start = time.monotonic()

    def report(sample: SimSample, flight: Flight) -> None:
        if report_to is not None:
            report_to(job.name, flight.stats.capture_frames, sample.state.sim_time_ns / 1e9)

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
    return _outcome(job, result, start)


def date_groups(jobs: Sequence[Job]) -> list[list[Job]]:
    """The jobs in groups of one scenario (setups equal but for the map date), in order."""
    groups: dict[tuple[str, object], list[Job]] = {}
    for job in jobs:
        key = (job.setup.name or "", replace(job.setup, map=replace(job.setup.map, date=None)))
        groups.setdefault(key, []).append(job)
    return list(groups.values())


def run_jobs(
    jobs: Sequence[Job],
    workers: int,
    *,
    on_progress: ReportFn,
    on_done: Callable[[Outcome], None],
    first: Callable[[Job], float] = lambda job: 0.0,
) -> list[Outcome]:
    """Fly ``jobs`` in ``workers`` processes (inline when 1), the lowest ``first(job)`` first;
    the outcomes come back in the order of ``jobs``."""
    groups = date_groups(jobs)
    if workers <= 1:
        done: dict[str, Outcome] = {}
        for group in sorted(groups, key=lambda g: min(first(j) for j in g)):
            for outcome in run_group(group, on_progress):
                on_done(outcome)
                done[outcome.name] = outcome
        return [done[job.name] for job in jobs]
    # Spawned, not forked: a fork copies the parent's threads' locks (OpenCV's thread pool,
    # zenoh) in whatever state they are, and a worker can hang on one; a caller that had
    # rendered in-process before running a pool hung this way.
    ctx = multiprocessing.get_context("spawn")
    progress = ctx.Queue()
    done = {}
    with ProcessPoolExecutor(
        max_workers=workers, mp_context=ctx, initializer=_init_worker, initargs=(progress,)
    ) as pool:
        futures: dict[Future[list[Outcome]], list[Job]] = {
            pool.submit(_run_in_worker, group): group
            for group in sorted(groups, key=lambda g: min(first(j) for j in g))
        }
        pending = set(futures)
        while pending:
            with contextlib.suppress(queue.Empty):
                on_progress(*progress.get(timeout=0.2))
            for fut in [f for f in pending if f.done()]:
                pending.discard(fut)
                try:
                    outcomes = fut.result()
                except Exception as err:  # a crashed worker: report it, keep the others
                    why = f"worker failed: {err!r}"
                    outcomes = [Outcome(name=j.name, error=why) for j in futures[fut]]
                for outcome in outcomes:
                    done[outcome.name] = outcome
                    on_done(outcome)
    return [done[job.name] for job in jobs]
