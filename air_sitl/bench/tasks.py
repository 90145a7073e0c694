"""The work of a bench: built-in methods over an archive, external localizers on the bus.

:func:`run_methods` localizes one archive with each method in turn and scores it (a process
pool runs one archive per worker: two methods never write one manifest at once).
:func:`run_external` flies a scenario again in lockstep with a user's localizer program on a
free loopback port, keeps its ``estimates/<name>.csv`` and scores it.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from air_sitl.bench.config import BenchConfig
from air_sitl.bench.results import EntryResult, archive_id, load, save
from air_sitl.errors import AirSitlError
from air_sitl.eval import score_sources
from air_sitl.localize.archive import run_archive
from air_sitl.localize.external import (
    ExternalLocalizer,
    adopt_estimates,
    fly_in_lockstep,
    same_flight,
)

Notify = Callable[[EntryResult], None]


@dataclass(frozen=True, slots=True, kw_only=True)
class MethodsTask:
    """One archive and the built-in methods still to measure on it."""

    scenario: str
    archive: Path
    methods: tuple[str, ...]
    reports: Path
    align: str
    reference_date: int
    seed: int


def _score(archive: Path, source: str, align: str) -> tuple[dict[str, object], object]:
    scored = score_sources(archive, [source], align)[0]
    return scored.report, scored.h_err_m


def run_methods(task: MethodsTask, notify: Notify | None = None) -> list[EntryResult]:
    """Localize and score each method on one archive; failures become one-line results."""
    ident = archive_id(task.archive)
    results: list[EntryResult] = []
    for method in task.methods:
        done = load(task.reports, task.scenario, method, ident)
        if done is not None:
            results.append(done)
            if notify is not None:
                notify(done)
            continue
        try:
            run = run_archive(
                task.archive,
                method,
                name=method,
                reference_date=task.reference_date,
                seed=task.seed,
            )
            report, errors = _score(task.archive, method, task.align)
            result = EntryResult(
                scenario=task.scenario,
                entry=method,
                report=report,
                localize_wall_s=round(run.wall_s, 3),
                frames_per_s=round(run.frames_per_s, 1),
            )
        except AirSitlError as err:
            result, errors = (
                EntryResult(scenario=task.scenario, entry=method, report=None, error=str(err)),
                None,
            )
        save(task.reports, result, ident, errors)  # type: ignore[arg-type]
        results.append(result)
        if notify is not None:
            notify(result)
    return results


def run_external(
    config: BenchConfig, scenario: str, archive: Path, localizer: ExternalLocalizer
) -> EntryResult:
    """Fly ``scenario`` in lockstep with the localizer program; score what it answered.

    The flight uses the archive's plan, map and options, so it is the same flight (checked:
    its trajectory.csv must equal the archive's byte for byte); its estimates file is moved
    into the archive and the flight's own folder removed. Otherwise the flight's folder is kept
    and scored instead.
    """
    ident = archive_id(archive)
    done = load(config.reports, scenario, localizer.name, ident)
    if done is not None:
        return done
    flight_dir = config.out / "external" / localizer.name / scenario
    if flight_dir.exists():
        shutil.rmtree(flight_dir)
    flight_dir.parent.mkdir(parents=True, exist_ok=True)
    fly_args = [
        *("--map", "urban" if scenario.upper().startswith("U") else "forest"),
        *("--map-date", str(config.flight_date), "--seed", str(config.seed)),
        *config.extra_dataset_args,
    ]
    log_path = flight_dir.parent / f"{scenario}.log"
    plan = config.missions / f"{scenario}.plan"
    why = fly_in_lockstep(plan, fly_args, flight_dir, localizer, log_path)
    if why is not None:
        msg = f"{localizer.name} on {scenario}: {why} (localizer log: {log_path})"
        return _failed(config, scenario, localizer.name, ident, msg)
    scored_archive = archive
    if same_flight(flight_dir, archive):
        adopt_estimates(flight_dir, archive, localizer.name)
        shutil.rmtree(flight_dir)
    else:
        scored_archive = flight_dir
    try:
        report, errors = _score(scored_archive, localizer.name, config.align)
    except AirSitlError as err:
        return _failed(config, scenario, localizer.name, ident, str(err))
    result = EntryResult(scenario=scenario, entry=localizer.name, report=report)
    save(config.reports, result, ident, errors)  # type: ignore[arg-type]
    return result


def _failed(config: BenchConfig, scenario: str, entry: str, ident: str, msg: str) -> EntryResult:
    result = EntryResult(scenario=scenario, entry=entry, report=None, error=msg)
    save(config.reports, result, ident, None)
    return result
