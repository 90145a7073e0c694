"""``air-sitl bench``: rank localization methods over the AIR scenarios; a preset of sweep.

    config = BenchConfig(scenarios=("UC-200",), methods=("deadreckon", "vo"), out=Path("b"), ...)
    board = run_bench(config)          # writes b/leaderboard.md, .json and b/error_boxes.png

Steps: the archives (made once with ``air-sitl dataset`` over the flight date, reused while
their inputs are unchanged); then a sweep (:mod:`air_sitl.sweep`) of one run per scenario, the
equivalent SPEC written to ``b/bench.yaml``, whose tasks point at those archives instead of
flying: each runs the built-in methods and the external localizers (in lockstep on the bus)
and scores them, on the sweep's executors (``-j N`` processes, or Ray), one row per scenario
in ``b/results.jsonl``. Every (scenario, entry) measurement is saved as it finishes
(:mod:`air_sitl.sweep.measurements`, ``b/reports/``), so an interrupted bench resumes where it
stopped. Last the leaderboard (:mod:`~air_sitl.bench.leaderboard`) and the box plots
(:mod:`~air_sitl.bench.plots`).
"""

from __future__ import annotations

import collections
import contextlib
import json
import shlex
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import IO, Any

import yaml

from air_sitl.bench.config import BenchConfig, ExternalLocalizer, parse_localizer, parse_methods
from air_sitl.bench.leaderboard import Leaderboard, build, gaps_json, gaps_markdown
from air_sitl.dataset.air_schema import MANIFEST_JSON
from air_sitl.errors import DatasetError
from air_sitl.files import write_bytes_atomic, write_json_atomic
from air_sitl.maps.dates import date_fields
from air_sitl.progress import Progress
from air_sitl.sweep import Executor, PoolExecutor, RayExecutor, make_tasks, run_tasks, time_parts
from air_sitl.sweep.measurements import EntryResult, archive_id, load_errors, read
from air_sitl.sweep.run import RunTask
from air_sitl.sweep.spec import SweepSpec, parse_spec

__all__ = [
    "BenchConfig",
    "ExternalLocalizer",
    "Leaderboard",
    "bench_spec",
    "parse_localizer",
    "parse_methods",
    "resume_problem",
    "run_bench",
    "run_gaps",
]

BENCH_SPEC = "bench.yaml"  # the sweep SPEC a bench is, written beside its results


class BenchProgress:
    """A line per measured cell (``bench [7/24] UC-200 mapmatch: median 2.1 m``) under a bar of the
    cells with their rate and ETA (:mod:`air_sitl.progress`)."""

    def __init__(self, total: int, stream: IO[str], quiet: bool, done: int = 0) -> None:
        self.total, self.done = total, done
        self.bar = Progress(  # cells measured before (a resumed bench) are not in the rate
            "bench", total, unit="cells", stream=stream, enabled=not quiet, initial=done
        )
        self.bar.update_to(done)

    def update(self, result: EntryResult) -> None:
        self.done += 1
        if result.error:
            what = f"failed: {result.error}"
        else:
            median = (result.report or {}).get("horizontal_error_m", {}).get("median")
            what = "no estimate" if median is None else f"median {median:.1f} m"
        self.bar.note(f"bench [{self.done}/{self.total}] {result.scenario} {result.entry}: {what}")
        self.bar.update_to(self.done)


def progress_note(stream: IO[str], line: str) -> None:
    """One line on the bench's stream."""
    stream.write(line + "\n")
    stream.flush()


def make_archives(
    config: BenchConfig, dates: tuple[int, ...] | None = None, out: Path | None = None
) -> None:
    """Fly the missing archives with ``air-sitl dataset --resume`` (complete ones are kept;
    an archive made with other inputs is refused by name, nothing is overwritten); over
    ``dates`` into ``out`` (``dataset``'s folders) instead of the bench's own date."""
    cmd = [
        sys.executable, "-m", "air_sitl", "dataset",
        "--scenarios", ",".join(config.scenarios),
        "--dates", ",".join(str(d) for d in dates or (config.flight_date,)),
        "--out", str(out or config.archives),
        "--missions", str(config.missions),
        "--seed", str(config.seed),
        "-j", str(config.jobs),
        "--resume",
    ]  # fmt: skip
    if config.map is not None:
        cmd += ["--map", config.map]
    if config.quiet:
        cmd.append("--quiet")
    # Its progress lines pass through as they come (a minute of flying is not silent); the
    # last ones say why when it fails.
    tail: collections.deque[str] = collections.deque(maxlen=50)
    with subprocess.Popen(
        cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, errors="replace"
    ) as proc:
        assert proc.stderr is not None
        for line in proc.stderr:
            tail.append(line)
            if not config.quiet:
                sys.stderr.write(line)
                sys.stderr.flush()
    if config.quiet and proc.returncode != 0:
        sys.stderr.write("".join(tail))
    err = "".join(tail)
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


def bench_spec(config: BenchConfig) -> dict[str, Any]:
    """The sweep SPEC a bench is: one run per scenario, flown as ``dataset`` flies it (the map
    date and seed of the bench), scored with the bench's methods and localizers; ``base``
    holds ``wait-timeout`` only when the bench was given one (so a bench without it writes
    the SPEC it wrote before)."""
    spec: dict[str, Any] = {}
    if config.wait_timeout_s is not None:
        spec["base"] = {"wait-timeout": config.wait_timeout_s}
    spec |= {
        "runs": [
            {
                "scenario": s,
                **({"map": config.map} if config.map is not None else {}),
                "map-date": config.flight_date,
                "seed": config.seed,
            }
            for s in config.scenarios
        ],
        "methods": list(config.methods),
    }
    if config.localizers:
        spec["localizers"] = {loc.name: shlex.join(loc.argv) for loc in config.localizers}
    spec["align"] = config.align
    spec["reference-date"] = config.reference_date
    return spec


def _tasks(config: BenchConfig, spec: SweepSpec) -> list[RunTask]:
    """The sweep's tasks, each pointing at its scenario's archive and keeping measurements."""
    tasks = make_tasks(spec, config.out)
    scenario_of = {run.id: run.options["scenario"] for run in spec.runs}
    return [
        replace(
            task,
            archive=str((config.archives / scenario_of[task.id]).resolve()),
            archive_label=f"{config.archives.name}/{scenario_of[task.id]}",
            reuse=True,
            measurements=str(config.reports.resolve()),
        )
        for task in tasks
    ]


def _row_results(task: RunTask, row: dict[str, Any]) -> list[EntryResult]:
    """A sweep row as the leaderboard's cells (what the progress line shows)."""
    reports = row.get("eval") or {}
    names = [*task.methods, *(loc.name for loc in task.localizers)]
    return [
        EntryResult(
            scenario=task.scenario,
            entry=name,
            report=reports.get(name),
            error=None if reports.get(name) is not None else (row.get("error") or "not run"),
        )
        for name in names
    ]


def _measured(config: BenchConfig, scenario: str, entry: str) -> EntryResult:
    ident = archive_id(config.archives / scenario)
    found = read(config.reports, scenario, entry, ident)
    if found is None:
        return EntryResult(scenario=scenario, entry=entry, report=None, error="not run")
    return found


def _executor(config: BenchConfig) -> Executor:
    if config.ray is not None:
        return RayExecutor(config.ray or None)
    return PoolExecutor(config.jobs)


def write_bench_spec(config: BenchConfig) -> SweepSpec:
    """Write ``OUT/bench.yaml`` (the bench as a sweep SPEC) and return it parsed. Written before
    anything flies: an interrupted bench says what it was (:mod:`air_sitl.outdir`, --resume)."""
    data = bench_spec(config)
    spec_path = config.out / BENCH_SPEC
    spec = parse_spec(data, spec_path, missions=config.missions)
    config.out.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(spec_path, yaml.safe_dump(data, sort_keys=False).encode("utf-8"))
    return spec


def run_bench(
    config: BenchConfig,
    stream: IO[str] | None = None,
    *,
    made: bool = False,
    executor: Executor | None = None,
) -> Leaderboard:
    """Make or reuse the archives, measure every (scenario, entry), write the leaderboard
    (``made``: the archives were just made for this bench, nothing to check or fly;
    ``executor``: where the runs go, by default the config's)."""
    stream = stream if stream is not None else sys.stderr
    config.out.mkdir(parents=True, exist_ok=True)
    for scenario in config.scenarios:  # archives kept from before: the bench's own message
        if (config.archives / scenario / MANIFEST_JSON).is_file():
            check_archive_inputs(config, scenario)
    spec = write_bench_spec(config)
    start = time.perf_counter()
    if not made:  # the flights and their rendering (dataset): nothing to fly when reused
        make_archives(config)
    if not config.quiet and not made:
        progress_note(stream, f"bench: archives {time.perf_counter() - start:.1f} s (fly, render)")
    missing = [s for s in config.scenarios if not (config.archives / s / MANIFEST_JSON).is_file()]
    if missing:
        msg = f"{config.archives}: no complete archive for {', '.join(missing)}"
        raise DatasetError(msg)
    cells = [(s, e) for s in config.scenarios for e in config.entries]
    measured = {cell for cell in cells if _measured(config, *cell).error is None}
    progress = BenchProgress(len(cells), stream, config.quiet, done=len(measured))

    def on_row(task: RunTask, row: dict[str, Any]) -> None:
        if not config.quiet and row.get("time_s"):
            progress.bar.note(f"bench {task.scenario}: {row['wall_s']:.1f} s{time_parts(row)}")
        for result in _row_results(task, row):
            if (result.scenario, result.entry) not in measured:
                progress.update(result)

    try:
        outcome = run_tasks(
            spec, _tasks(config, spec), config.out, executor or _executor(config), on_row=on_row
        )
    finally:
        progress.bar.close()
    if outcome.interrupted:
        raise KeyboardInterrupt
    results = [_measured(config, *cell) for cell in cells]
    dates = (config.reference_date, config.flight_date)
    board = build(config.entries, config.scenarios, results, dates, _map_dates(config))
    write_json_atomic(config.out / "leaderboard.json", board.to_json())
    write_bytes_atomic(config.out / "leaderboard.md", board.to_markdown().encode("utf-8"))
    errors = {
        (r.entry, r.scenario): e
        for r in results
        if r.error is None and (e := load_errors(config.reports, r.scenario, r.entry)) is not None
    }
    if errors:
        from air_sitl.bench.plots import error_boxes  # matplotlib only when there is a plot

        error_boxes(errors, config.entries, config.scenarios, config.out / "error_boxes.png", dates)
    return board


def _map_dates(config: BenchConfig) -> tuple[str | None, ...]:
    """The acquisition dates of the flights' maps, as the archives' manifests name them; the
    worlds keep their own calendars (farmland's surveys are NAIP's growing season): where
    the scenarios' maps differ, an index's dates are joined, ``2016-04-22 / 2016-08-13``."""
    by_index: list[list[str]] = []
    for scenario in config.scenarios:
        path = config.archives / scenario / MANIFEST_JSON
        info = json.loads(path.read_text()).get("map") if path.is_file() else None
        for i, when in enumerate(date_fields(info)["dates"] if isinstance(info, dict) else ()):
            while len(by_index) <= i:
                by_index.append([])
            if when and when not in by_index[i]:
                by_index[i].append(str(when))
    return tuple(" / ".join(names) or None for names in by_index)


def fly_dates_once(config: BenchConfig, flight_dates: tuple[int, ...], stream: IO[str]) -> bool:
    """The archives of every flight date, each scenario flown once for all its dates
    (``dataset`` renders each date from the same flight, byte-identical to flying it):
    made under ``OUT/flights/`` and moved to each date's bench (``OUT/date<N>/archives/``).
    Scenarios with any of those archives already there are left to each date's bench.
    True when every scenario's archives were made here (the benches need not check them)."""
    configs = {d: replace(config, flight_date=d, out=config.out / f"date{d}") for d in flight_dates}
    fresh = tuple(
        s for s in config.scenarios if not any((c.archives / s).exists() for c in configs.values())
    )
    if not fresh or len(flight_dates) < 2:
        return False
    staging = config.out / "flights"
    start = time.perf_counter()
    make_archives(replace(config, scenarios=fresh), flight_dates, staging)
    if not config.quiet:
        took = time.perf_counter() - start
        progress_note(stream, f"bench: archives of dates {flight_dates} {took:.1f} s (fly, render)")
    for scenario in fresh:
        for d, c in configs.items():
            made = staging / f"{scenario}@{d}"
            if (made / MANIFEST_JSON).is_file():
                c.archives.mkdir(parents=True, exist_ok=True)
                made.replace(c.archives / scenario)
    return fresh == config.scenarios


def resume_problem(config: BenchConfig, flight_dates: tuple[int, ...]) -> str | None:
    """None when ``config.out`` holds a bench of these inputs (its ``bench.yaml``, one per
    flight date: ``--resume`` continues it), else why not (:mod:`air_sitl.outdir`)."""
    configs = [config]
    if len(flight_dates) > 1:
        configs = [
            replace(config, flight_date=d, out=config.out / f"date{d}") for d in flight_dates
        ]
    found = False
    for one in configs:
        path = one.out / BENCH_SPEC
        if not path.is_file():
            continue
        found = True
        try:
            there = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, yaml.YAMLError):
            return f"{path} is unreadable"
        wanted = bench_spec(one)
        keys = [k for k in {**wanted, **(there if isinstance(there, dict) else {})}]
        diff = [k for k in keys if not isinstance(there, dict) or there.get(k) != wanted.get(k)]
        if diff:
            return f"a bench of other inputs: {', '.join(diff)} differ in {path}"
    return None if found else f"not a bench folder: no {BENCH_SPEC}"


def run_gaps(
    config: BenchConfig, flight_dates: tuple[int, ...], stream: IO[str] | None = None
) -> list[Leaderboard]:
    """One bench per flight date (``OUT/date<N>/``, each with its archives and leaderboard),
    all against the reference date; ``OUT/leaderboard.md`` and ``.json`` compare the gaps.
    The flights are flown once for all dates (:func:`fly_dates_once`)."""
    config.out.mkdir(parents=True, exist_ok=True)
    for d in flight_dates:  # every date's bench.yaml first: an interruption stays resumable
        write_bench_spec(replace(config, flight_date=d, out=config.out / f"date{d}"))
    made = fly_dates_once(config, flight_dates, stream if stream is not None else sys.stderr)
    # One pool of workers for every date: started once, and a method that reads no imagery
    # is localized and scored once per flight, its result reused for the other dates
    # (:mod:`air_sitl.sweep.reuse`; a worker keeps it, so with -j 1 every date finds it).
    executor = _executor(config)
    with executor if isinstance(executor, PoolExecutor) else contextlib.nullcontext():
        boards = [
            run_bench(
                replace(config, flight_date=d, out=config.out / f"date{d}"),
                stream,
                made=made,
                executor=executor,
            )
            for d in flight_dates
        ]
    write_json_atomic(config.out / "leaderboard.json", gaps_json(boards))
    write_bytes_atomic(config.out / "leaderboard.md", gaps_markdown(boards).encode("utf-8"))
    return boards
