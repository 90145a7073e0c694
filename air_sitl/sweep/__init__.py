"""``air-sitl sweep``: many runs (fly, localize, eval) from one SPEC, resumable, on a pool or Ray.

    spec = load_spec(Path("sweep.yaml"))                       # validated once (spec.py)
    outcome = run_sweep(spec, Path("out/sweep"), PoolExecutor(2))   # -> out/sweep/results.jsonl
    write_report(Path("out/sweep"))                            # report.md + report.png

One concern per module: :mod:`.spec` (the SPEC and each run's options, checked by fly's own
parser), :mod:`.run` (the work of one run in a worker), :mod:`.groups` (runs that differ only
in the map date, one task flying once), :mod:`.executors` (process pool, Ray),
:mod:`.results` (``results.jsonl``: whole lines, resume), :mod:`.report` (tables and plots).
The driver here turns runs into tasks, skips the done ones, and writes each row as it comes.
``air-sitl bench`` is a preset of it (:mod:`air_sitl.bench`): one run per AIR scenario, the tasks
pointing at the archives ``dataset`` made, each entry's measurement kept
(:mod:`.measurements`).
"""

from __future__ import annotations

import contextlib
import json
import socket
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Protocol

from air_sitl.files import write_json_atomic
from air_sitl.progress import Progress
from air_sitl.sweep.errors import SweepError
from air_sitl.sweep.executors import PoolExecutor, RayExecutor
from air_sitl.sweep.groups import Group, group_tasks
from air_sitl.sweep.measurements import archive_id, load
from air_sitl.sweep.results import RESULTS, ResultsFile, latest_rows
from air_sitl.sweep.run import RunTask
from air_sitl.sweep.spec import KEEP, SweepSpec, describe, load_spec, needs_camera

__all__ = [
    "PoolExecutor",
    "RayExecutor",
    "SweepError",
    "SweepOutcome",
    "SweepSpec",
    "load_spec",
    "make_tasks",
    "print_outcome",
    "resume_problem",
    "run_sweep",
    "run_tasks",
    "time_parts",
]

SWEEP_JSON = "sweep.json"  # what the sweep folder holds: the SPEC, its axes and methods
RUNS_DIR = "runs"


class Executor(Protocol):
    workers: int  # runs at once (tasks are split to keep them busy), 1 when unknown

    def run(self, groups: Sequence[Group], on_row: Any) -> None: ...


@dataclass(frozen=True, slots=True, kw_only=True)
class SweepOutcome:
    """What a sweep did: runs in the SPEC, skipped as done, run now, failed now."""

    total: int
    skipped: int
    ran: int
    failed: int
    interrupted: bool = False
    failed_total: int = 0  # runs of the SPEC whose latest row is a failure (earlier ones too)
    hosts: dict[str, int] | None = None  # host -> runs it ran now


def _label(path: Path, out: Path) -> str:
    try:
        return str(path.relative_to(out))
    except ValueError:
        return str(path)


def make_tasks(spec: SweepSpec, out: Path, keep: str = "all") -> list[RunTask]:
    """One task per run of ``spec`` (plan text read once per plan file)."""
    if keep not in KEEP:
        msg = f"--keep {keep!r}: expected one of {', '.join(KEEP)}"
        raise SweepError(msg)
    out = out.resolve()
    root = spec.archives if spec.archives is not None else out / RUNS_DIR
    texts: dict[Path, bytes] = {}
    tasks = []
    for run in spec.runs:
        if run.plan_path not in texts:
            try:
                texts[run.plan_path] = run.plan_path.read_bytes()
            except OSError as err:
                msg = f"{spec.path}: {run.plan_label}: cannot read the plan: {err.strerror}"
                raise SweepError(msg) from None
        archive = root / run.id
        tasks.append(
            RunTask(
                id=run.id,
                options=run.options,
                plan_label=run.plan_label,
                plan_name=run.plan_path.name,
                plan_path=str(run.plan_path),
                plan_text=texts[run.plan_path],
                argv=run.argv,
                seed=run.seed,
                archive=str(archive),
                archive_label=_label(archive, out),
                methods=spec.methods,
                localizers=spec.localizers,
                align=spec.align,
                keep=keep,
                reference_date=spec.reference_date,
            )
        )
    return tasks


class _Progress:
    """A line per finished run (``sweep [7/16] 3f2a.. map-date=1 seed=2: 1.4 s, deadreckon 2.1 m``)
    under a bar of the runs with their rate and ETA (:mod:`air_sitl.progress`)."""

    def __init__(self, total: int, done: int, stream: IO[str] | None, axes: Sequence[str]):
        self.total, self.done, self.stream, self.axes = total, done, stream, axes
        self.bar = Progress(  # runs done before (a resumed sweep) are not in the rate
            "sweep", total, unit="runs", stream=stream, enabled=stream is not None, initial=done
        )
        self.bar.update_to(done)

    def update(self, row: dict[str, Any], what: str) -> None:
        self.done += 1
        if row.get("error"):
            result = f"failed: {row['error']}"
        else:
            parts = [f"{row['wall_s']:.1f} s{time_parts(row)}"]
            for name, report in (row.get("eval") or {}).items():
                median = ((report or {}).get("horizontal_error_m") or {}).get("median")
                parts.append(f"{name} {'-' if median is None else f'{median:.1f} m'}")
            result = ", ".join(parts)
        self.bar.note(f"sweep [{self.done}/{self.total}] {what}: {result}")
        self.bar.update_to(self.done)

    def close(self) -> None:
        self.bar.close()


def time_parts(row: dict[str, Any]) -> str:
    """`` (fly 40.1 s, localize 3.0 s, eval 0.2 s)``: where a row's wall time went."""
    times = row.get("time_s") or {}
    if not times:
        return ""
    return " (" + ", ".join(f"{k} {v:.1f} s" for k, v in times.items()) + ")"


def _all_measured(task: RunTask) -> bool:
    """Every entry of a task that keeps measurements is measured, on the archive its folder
    holds now (a failed entry is not: it is tried again)."""
    assert task.measurements is not None
    try:
        ident = archive_id(Path(task.archive))
    except (OSError, ValueError, KeyError):
        return False
    names = [*task.methods, *(loc.name for loc in task.localizers)]
    return all(load(Path(task.measurements), task.scenario, n, ident) is not None for n in names)


def _is_done(task: RunTask, row: dict[str, Any] | None, retry_failed: bool) -> bool:
    if task.measurements is not None:
        return _all_measured(task)
    if row is None:
        return False
    if row.get("error") and retry_failed:
        return False
    wanted = {*task.methods, *(loc.name for loc in task.localizers)}
    return row.get("error") is not None or wanted <= set(row.get("eval") or {})


def _sweep_record(spec: SweepSpec, tasks: Sequence[RunTask]) -> dict[str, Any]:
    """What ``sweep.json`` holds: the SPEC, its axes, methods and runs."""
    return {
        "spec": str(spec.path.resolve()),
        "axes": list(spec.axes),
        "methods": list(spec.methods),
        "localizers": [loc.name for loc in spec.localizers],
        "align": spec.align,
        "runs": [t.id for t in tasks],
    }


def resume_problem(spec: SweepSpec, out: Path, keep: str = "all") -> str | None:
    """None when ``out`` holds a sweep of ``spec`` (``--resume`` continues it), else why not
    (:mod:`air_sitl.outdir`)."""
    try:
        found = json.loads((out / SWEEP_JSON).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return f"not a sweep folder: no readable {SWEEP_JSON}"
    wanted = _sweep_record(spec, make_tasks(spec, out, keep))
    diff = [k for k in wanted if not isinstance(found, dict) or found.get(k) != wanted[k]]
    return f"a sweep of other inputs: {', '.join(diff)} differ" if diff else None


def run_sweep(
    spec: SweepSpec,
    out: Path,
    executor: Executor,
    *,
    keep: str = "all",
    retry_failed: bool = False,
    stream: IO[str] | None = None,
) -> SweepOutcome:
    """Run every run of ``spec`` not done yet in ``out``; rows into ``out/results.jsonl``.

    KeyboardInterrupt stops the executor and returns an interrupted outcome: the rows written
    are whole, and the same call later resumes.
    """
    needs_camera(spec)
    tasks = make_tasks(spec, out, keep)
    return run_tasks(spec, tasks, out, executor, retry_failed=retry_failed, stream=stream)


def run_tasks(
    spec: SweepSpec,
    tasks: Sequence[RunTask],
    out: Path,
    executor: Executor,
    *,
    retry_failed: bool = False,
    stream: IO[str] | None = None,
    on_row: Callable[[RunTask, dict[str, Any]], None] | None = None,
) -> SweepOutcome:
    """Run the tasks of ``spec`` (:func:`make_tasks`, perhaps adjusted: bench's point at
    archives) not done yet in ``out``; each row into ``out/results.jsonl``, then to ``on_row``
    with its task."""
    out.mkdir(parents=True, exist_ok=True)
    results_path = out / RESULTS
    rows = latest_rows(results_path)
    todo = [t for t in tasks if not _is_done(t, rows.get(t.id), retry_failed)]
    write_json_atomic(out / SWEEP_JSON, _sweep_record(spec, tasks))
    by_id = {run.id: run for run in spec.runs}
    task_of = {t.id: t for t in tasks}
    progress = _Progress(len(tasks), len(tasks) - len(todo), stream, spec.axes)
    failed = 0
    hosts: dict[str, int] = {}
    interrupted = False
    with ResultsFile(results_path) as results:

        def take_row(row: dict[str, Any]) -> None:
            nonlocal failed
            results.append(row)
            failed += bool(row.get("error"))
            host = row.get("host") or "?"
            hosts[host] = hosts.get(host, 0) + 1
            run = by_id[row["id"]]
            progress.update(row, f"{row['id']} {describe(run, spec.axes)}")
            if on_row is not None:
                on_row(task_of[row["id"]], row)

        try:
            if todo:  # the map dates of one flight fly once (groups), longest first
                executor.run(group_tasks(todo, executor.workers), take_row)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            progress.close()
    rows = latest_rows(results_path)
    failed_total = sum(1 for t in tasks if (rows.get(t.id) or {}).get("error"))
    return SweepOutcome(
        failed_total=failed_total,
        total=len(tasks),
        skipped=len(tasks) - len(todo),
        ran=sum(hosts.values()),
        failed=failed,
        interrupted=interrupted,
        hosts=hosts,
    )


def print_outcome(outcome: SweepOutcome, out: Path, stream: IO[str]) -> None:
    """The closing lines of a sweep: counts, where the archives are, what to run next."""
    with contextlib.suppress(Exception):
        stream.flush()
    state = "interrupted" if outcome.interrupted else "done"
    print(
        f"sweep {state}: {outcome.ran} run now ({outcome.failed} failed), {outcome.skipped} "
        f"already done, {outcome.total} in the SPEC ({outcome.failed_total} failed) -> "
        f"{out / RESULTS}",
        file=stream,
    )
    here = socket.gethostname()
    others = {h: n for h, n in (outcome.hosts or {}).items() if h not in (here, "?")}
    for host, n in sorted(others.items()):
        print(f"  {n} run folder(s) written on {host} (rows: host, archive)", file=stream)
    if outcome.interrupted:
        print("  run the same command with --resume to continue", file=stream)
    else:
        print(f"  report: air-sitl sweep report {out}", file=stream)
