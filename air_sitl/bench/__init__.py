"""``air-sitl bench``: rank localization methods over the AIR scenarios.

    config = BenchConfig(scenarios=("UC-200",), methods=("deadreckon", "vo"), out=Path("b"), ...)
    board = run_bench(config)          # writes b/leaderboard.md, .json and b/error_boxes.png

Steps: the archives (made once with ``air-sitl dataset`` over the flight date, reused while
their inputs are unchanged), each built-in method localized and scored per archive on a pool
of ``jobs`` processes (:mod:`~air_sitl.bench.tasks`), each external localizer flown in
lockstep on the bus per scenario, then the leaderboard (:mod:`~air_sitl.bench.leaderboard`)
and the box plots (:mod:`~air_sitl.bench.plots`). Every measurement is saved as it finishes
(:mod:`~air_sitl.bench.results`), so an interrupted bench resumes where it stopped.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import queue
import subprocess
import sys
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor
from typing import IO, Any

from air_sitl.bench.config import BenchConfig, ExternalLocalizer, parse_localizer, parse_methods
from air_sitl.bench.leaderboard import Leaderboard, build
from air_sitl.bench.results import EntryResult, load_errors
from air_sitl.bench.tasks import MethodsTask, run_external, run_methods
from air_sitl.dataset.air_schema import MANIFEST_JSON
from air_sitl.errors import DatasetError
from air_sitl.files import write_bytes_atomic, write_json_atomic

__all__ = [
    "BenchConfig",
    "ExternalLocalizer",
    "Leaderboard",
    "parse_localizer",
    "parse_methods",
    "run_bench",
]

_QUEUE: Any = None  # the progress queue of a pool worker


class Progress:
    """``bench [#####.....] 7/24  UC-200 mapmatch: median 2.1 m`` (in place on a terminal)."""

    def __init__(self, total: int, stream: IO[str], quiet: bool) -> None:
        self.total, self.done, self.stream, self.quiet = total, 0, stream, quiet
        self.tty = stream.isatty()

    def update(self, result: EntryResult) -> None:
        self.done += 1
        if self.quiet:
            return
        filled = int(30 * self.done / max(1, self.total))
        if result.error:
            what = f"failed: {result.error}"
        else:
            median = (result.report or {}).get("horizontal_error_m", {}).get("median")
            what = "no estimate" if median is None else f"median {median:.1f} m"
        line = (
            f"bench [{'#' * filled}{'.' * (30 - filled)}] {self.done}/{self.total}  "
            f"{result.scenario} {result.entry}: {what}"
        )
        if self.tty:
            self.stream.write("\r\x1b[K" + line[:160])
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def make_archives(config: BenchConfig) -> None:
    """Fly the missing archives with ``air-sitl dataset --resume`` (complete ones are kept;
    an archive made with other inputs is refused by name, nothing is overwritten)."""
    cmd = [
        sys.executable, "-m", "air_sitl", "dataset",
        "--scenarios", ",".join(config.scenarios),
        "--dates", str(config.flight_date),
        "--out", str(config.archives),
        "--missions", str(config.missions),
        "--seed", str(config.seed),
        "-j", str(config.jobs),
        "--resume",
        *config.extra_dataset_args,
    ]  # fmt: skip
    if config.quiet:
        cmd.append("--quiet")
    proc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False)
    err = proc.stderr.decode("utf-8", "replace")
    if not config.quiet or proc.returncode != 0:
        sys.stderr.write(err)
    if proc.returncode not in (0, 1):  # 1: a mission did not complete; still scored
        lines = [ln for ln in err.splitlines() if "error" in ln] or err.splitlines()[-1:]
        why = lines[-1] if lines else f"exit {proc.returncode}"
        msg = f"{config.archives}: making the archives failed: {why}"
        raise DatasetError(msg)


def check_archive_inputs(config: BenchConfig, scenario: str) -> None:
    """A reused archive must be the flight this bench asks for: its manifest says so."""
    archive = config.archives / scenario
    manifest = json.loads((archive / MANIFEST_JSON).read_text(encoding="utf-8"))
    found = {
        "map date": manifest.get("map", {}).get("date_index"),
        "seed": manifest.get("flight", {}).get("seed"),
    }
    wanted = {"map date": config.flight_date, "seed": config.seed}
    for key, value in wanted.items():
        if found[key] != value:
            msg = (
                f"{archive / MANIFEST_JSON}: {key} {found[key]!r}, but this bench flies "
                f"{key} {value}: choose another --out (archives are reused, never overwritten)"
            )
            raise DatasetError(msg)


def _init_worker(progress: Any) -> None:
    global _QUEUE  # noqa: PLW0603  (one queue per worker process)
    _QUEUE = progress


def _pool_task(task: MethodsTask) -> list[EntryResult]:
    return run_methods(task, notify=_QUEUE.put if _QUEUE is not None else None)


def _run_method_tasks(
    tasks: list[MethodsTask], jobs: int, notify: Callable[[EntryResult], None]
) -> list[EntryResult]:
    if jobs <= 1 or len(tasks) <= 1:
        return [r for task in tasks for r in run_methods(task, notify=notify)]
    ctx = multiprocessing.get_context("spawn")  # see commands/dataset: forked workers can hang
    progress = ctx.Queue()
    results: list[EntryResult] = []
    with ProcessPoolExecutor(
        max_workers=jobs, mp_context=ctx, initializer=_init_worker, initargs=(progress,)
    ) as pool:
        futures: list[Future[list[EntryResult]]] = [pool.submit(_pool_task, t) for t in tasks]
        pending = set(futures)
        while pending:
            with contextlib.suppress(queue.Empty):
                notify(progress.get(timeout=0.2))
            for fut in [f for f in pending if f.done()]:
                pending.discard(fut)
                results.extend(fut.result())
        while True:  # what arrived after the last future finished
            try:
                notify(progress.get_nowait())
            except queue.Empty:
                break
    return results


def run_bench(config: BenchConfig, stream: IO[str] | None = None) -> Leaderboard:
    """Make or reuse the archives, measure every (scenario, entry), write the leaderboard."""
    stream = stream if stream is not None else sys.stderr
    config.out.mkdir(parents=True, exist_ok=True)
    make_archives(config)
    missing = [s for s in config.scenarios if not (config.archives / s / MANIFEST_JSON).is_file()]
    if missing:
        msg = f"{config.archives}: no complete archive for {', '.join(missing)}"
        raise DatasetError(msg)
    for scenario in config.scenarios:
        check_archive_inputs(config, scenario)
    total = len(config.scenarios) * len(config.entries)
    progress = Progress(total, stream, config.quiet)
    tasks = [
        MethodsTask(
            scenario=s,
            archive=config.archives / s,
            methods=config.methods,
            reports=config.reports,
            align=config.align,
            reference_date=config.reference_date,
            seed=config.seed,
        )
        for s in config.scenarios
    ]
    results = _run_method_tasks(tasks, config.jobs, progress.update) if config.methods else []
    for localizer in config.localizers:
        for s in config.scenarios:
            result = run_external(config, s, config.archives / s, localizer)
            progress.update(result)
            results.append(result)
    board = build(config.entries, config.scenarios, results)
    write_json_atomic(config.out / "leaderboard.json", board.to_json())
    write_bytes_atomic(config.out / "leaderboard.md", board.to_markdown().encode("utf-8"))
    errors = {
        (r.entry, r.scenario): e
        for r in results
        if r.error is None and (e := load_errors(config.reports, r.scenario, r.entry)) is not None
    }
    if errors:
        from air_sitl.bench.plots import error_boxes  # matplotlib only when there is a plot

        error_boxes(errors, config.entries, config.scenarios, config.out / "error_boxes.png")
    return board
