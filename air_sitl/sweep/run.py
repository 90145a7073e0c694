"""The work of one run, in whichever worker runs it: fly, localize with each method, score.

:func:`execute` takes a :class:`RunTask` (small, picklable: the plan's text travels with it, so
a worker on another host needs no copy of the SPEC's folder) and returns the row of
``results.jsonl`` (small too); the archive stays where ``RunTask.archive`` says, on the
worker's filesystem. A run's failure is its row's one-line ``error``, never an exception:
the sweep goes on. Wall-clock figures of ``summary.json`` (``wall_time_s``,
``realtime_factor``) stay in the archive and out of the row, which is the same on every
executor but for ``wall_s``, ``host`` and ``time_s``. :func:`execute_group` runs the map dates
of one flight (:mod:`.groups`): flown once, every date's archive rendered from the same
samples, then each run localized and scored as :func:`execute` does. A task with ``reuse``
flies nothing and scores the archive already in its folder (``air-sitl bench``: a sweep over
the archives ``dataset`` made); one with ``measurements`` saves each entry's measurement as
it finishes (:mod:`~air_sitl.sweep.measurements`) and skips the entries measured before.

Per worker process, one core: a procedural map is opened once and kept for every later run
over the same map (:data:`_MAPS`), the flights' and the map matchers' reference maps alike,
drawing their ground into the pool's shared folder; a run's methods go over its archive in one
pass (each frame read and decoded once); BLAS and OpenCV run one thread (:func:`pin_threads`); the
camera renders on the simulation thread (``--render-workers 0``) and the archive's files are
written there too (no I/O thread: a second thread in a worker only competes for its core and
the GIL).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import shutil
import socket
import time
from collections import OrderedDict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2

from air_sitl.builder import load_setup
from air_sitl.bus.hookup import bus_sinks_from_args
from air_sitl.camera.options import camera_from_args, map_choice_from_args
from air_sitl.dataset.air_schema import ESTIMATES_DIR, SUMMARY_JSON
from air_sitl.errors import AirSitlError, DatasetError
from air_sitl.eval import Scored, score_sources
from air_sitl.localize.archive import LocalizeRun, run_archive_methods
from air_sitl.localize.external import (
    ExternalLocalizer,
    adopt_estimates,
    fly_in_lockstep,
    same_flight,
)
from air_sitl.maps.base import MapSource
from air_sitl.maps.choose import open_chosen_map
from air_sitl.maps.open import default_map_for_plan, open_map
from air_sitl.maps.procedural import KINDS
from air_sitl.options import flight_options_from_args, int_in_range
from air_sitl.recording import RecordingRequest, record_flight
from air_sitl.recording.dates import record_dates, shares_flight
from air_sitl.recording.timing import OwnTime
from air_sitl.sweep import reuse
from air_sitl.sweep.measurements import EntryResult, archive_id, load, save
from air_sitl.sweep.spec import fly_parser

WALL_CLOCK_SUMMARY_KEYS = ("wall_time_s", "realtime_factor")
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")
MAPS_KEPT = 4  # procedural maps a worker keeps open (each caches up to 256 MB of tiles)

_MAPS: OrderedDict[tuple[Any, ...], Any] = OrderedDict()
# Where the workers of one pool share the procedural maps' drawn ground (None: alone).
_SHARED_GROUND: list[Path | None] = [None]


@dataclass(frozen=True, slots=True, kw_only=True)
class RunTask:
    """One run as a worker receives it."""

    id: str
    options: dict[str, Any]
    plan_label: str
    plan_name: str  # file name of the plan (its stem names the scenario)
    # The plan file the SPEC named, on the driver (absolute): what the run's summary.json
    # records as its plan, not the copy the worker flies (from the run's working folder).
    plan_path: str
    plan_text: bytes
    argv: tuple[str, ...]
    seed: int
    archive: str  # the run's folder on the worker (absolute)
    archive_label: str  # how the row names it: relative to the sweep folder when inside it
    methods: tuple[str, ...] = ()
    localizers: tuple[ExternalLocalizer, ...] = ()
    align: str = "none"
    keep: str = "all"
    reference_date: int | None = None  # map-matching methods' reference map date (None: theirs)
    # The folder holds this run's flight already (an archive ``air-sitl dataset`` made, which
    # bench scores): nothing flies, the methods and localizers run over it.
    reuse: bool = False
    measurements: str | None = None  # per-entry measurements saved here (sweep.measurements)

    @property
    def scenario(self) -> str:
        """The plan file's stem: AIR's scenario name (``UC-200``), what measurements file under."""
        return Path(self.plan_name).stem


def pin_threads() -> None:
    """One thread for BLAS (environment, for libraries not loaded yet) and OpenCV."""
    for name in THREAD_ENV:
        os.environ[name] = "1"
    cv2.setNumThreads(1)


def _finite(value: Any) -> Any:
    """JSON-safe: NaN and infinities become null, recursively."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: _finite(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_finite(v) for v in value]
    return value


def _one_line(err: BaseException) -> str:
    text = str(err).strip().splitlines()
    first = text[0] if text else ""
    if isinstance(err, AirSitlError):
        return first or type(err).__name__
    return f"{type(err).__name__}: {first}" if first else type(err).__name__


def share_ground_through(folder: Path | None) -> None:
    """This worker's procedural maps share their drawn ground with the pool's other workers
    through ``folder`` (:mod:`air_sitl.maps.procedural.shared_tiles`; the same pixels)."""
    _SHARED_GROUND[0] = folder


def _cached_map(setup: Any) -> Any:
    """The procedural map of ``setup``, opened once per worker; None for GeoTIFF maps (a
    flight closes its map's files when it ends)."""

    spec = setup.map.spec or default_map_for_plan(setup.name)
    if spec.strip() not in KINDS:
        return None
    home = setup.home
    key = (spec.strip(), setup.map.seed, setup.map.date, home.lat_deg, home.lon_deg)
    return _kept(
        key,
        lambda: open_chosen_map(replace(setup.map, shared_dir=_SHARED_GROUND[0]), home, setup.name),
    )


def reference_map(
    spec: str, home: Any, *, seed: int = 0, date: str | int | None = None
) -> MapSource:
    """A map-matching method's reference map (``open_map``'s signature): a procedural one
    opened once per worker and kept, drawing into the pool's shared ground (a run's date-0
    flight has drawn most of it); a GeoTIFF opened as the method would."""
    if spec.strip() not in KINDS:
        return open_map(spec, home, seed=seed, date=date)
    key = ("reference", spec.strip(), seed, str(date), home.lat_deg, home.lon_deg)
    source: MapSource = _kept(
        key, lambda: open_map(spec, home, seed=seed, date=date, shared_dir=_SHARED_GROUND[0])
    )
    return source


def _kept(key: tuple[Any, ...], opener: Any) -> Any:
    """The map kept under ``key`` (the least recently used one goes beyond MAPS_KEPT)."""
    if key in _MAPS:
        _MAPS.move_to_end(key)
        return _MAPS[key]
    source = opener()
    _MAPS[key] = source
    while len(_MAPS) > MAPS_KEPT:
        _MAPS.popitem(last=False)
    return source


def _with_free_port(argv: list[str]) -> list[str]:
    """A bus on a loopback port the system picks as it listens (port 0: nothing can take it
    first) unless the SPEC gave one: runs side by side never share 7447."""
    if "--zenoh" in argv and not any(a.startswith("--zenoh-listen") for a in argv):
        return [*argv, "--zenoh-listen=tcp/127.0.0.1:0"]
    return argv


def _request(task: RunTask, plan: Path, own_time: OwnTime) -> RecordingRequest:
    """The recording of the run into its folder, as ``air-sitl fly`` would make it."""
    args = fly_parser().parse_args([str(plan), *_with_free_port(list(task.argv))])
    setup = load_setup(
        plan,
        flight_options_from_args(args),
        camera=None if args.no_camera else camera_from_args(args),
        map=map_choice_from_args(args),
        render_workers=int_in_range("--render-workers", args.render_workers, 0, 64),
    )
    if setup.camera is not None:
        setup = replace(setup, map_source=_cached_map(setup))
    hookup = bus_sinks_from_args(args)
    return RecordingRequest(
        setup=setup,
        out=Path(task.archive),
        bus=hookup if hookup.options is not None else None,
        io_thread=False,
        summary_plan=task.plan_path,
        own_time=own_time,
    )


def _fly(task: RunTask, plan: Path, own_time: OwnTime) -> dict[str, Any]:
    """Fly the run into its folder, as ``air-sitl fly`` would; its summary.json."""
    request = _request(task, plan, own_time)
    with request.bus or contextlib.nullcontext():
        record_flight(request)
    return _read_summary(request.out)


def _read_summary(out: Path) -> dict[str, Any]:
    try:
        summary: dict[str, Any] = json.loads((out / SUMMARY_JSON).read_text(encoding="utf-8"))
    except FileNotFoundError:
        msg = f"{out}: no {SUMMARY_JSON}: not a finished flight"
        raise DatasetError(msg) from None
    return summary


def _row_summary(summary: dict[str, Any], plan_label: str) -> dict[str, Any]:
    kept = {k: v for k, v in summary.items() if k not in WALL_CLOCK_SUMMARY_KEYS}
    kept["plan"] = plan_label  # the SPEC's name for it, the same on every host
    return dict(sorted(kept.items()))


def _run_methods(task: RunTask, out: Path, methods: list[str]) -> dict[str, LocalizeRun | str]:
    """The methods over the run's archive in one pass (each frame read and decoded once):
    each method's run, or why it failed. When the pass fails, each method alone, so that
    each says its own reason and the others are measured."""
    if not methods:
        return {}
    try:
        runs = run_archive_methods(
            out,
            [(method, method, {}) for method in methods],
            reference_date=task.reference_date,
            seed=task.seed,
            open_map=reference_map,
        )
    except AirSitlError as err:
        if len(methods) == 1:
            return {methods[0]: f"localize {methods[0]}: {_one_line(err)}"}
        return {m: got for one in methods for m, got in _run_methods(task, out, [one]).items()}
    return {run.name: run for run in runs}


def _measure(
    task: RunTask,
    out: Path,
    entry: str | ExternalLocalizer,
    ran: dict[str, LocalizeRun | str],
    times: dict[str, float],
    key: reuse.Key | None = None,
) -> tuple[Scored | None, str | None, LocalizeRun | None]:
    """One method's run (from ``ran``), or one localizer program in lockstep, then its
    estimate scored (or its score kept under ``key``: :mod:`.reuse`): (the score, why it
    failed, the method's run); the seconds each took are added to ``times`` (``localize``,
    ``eval``)."""
    name = entry if isinstance(entry, str) else entry.name
    run = None
    if isinstance(entry, str):
        got = ran[entry]
        if isinstance(got, str):
            return None, got, None
        run = got
    else:
        start = time.perf_counter()
        try:
            why = _run_external(task, out, entry)
        finally:
            times["localize"] += time.perf_counter() - start
        if why is not None:
            return None, f"localizer {name}: {why}", None
    start = time.perf_counter()
    try:
        scored = reuse.score(key, task.align, lambda: score_sources(out, [name], task.align)[0])
    except AirSitlError as err:
        return None, f"eval: {_one_line(err)}", run
    finally:
        times["eval"] += time.perf_counter() - start
    scored.report["archive"] = task.archive_label
    return scored, None, run


def _localize(
    task: RunTask, out: Path, times: dict[str, float]
) -> tuple[dict[str, Any], str | None]:
    """The methods in one pass, then each entry scored in turn (and saved as it finishes
    when the task keeps measurements; those measured before are not measured again);
    (reports, first error)."""
    folder = None if task.measurements is None else Path(task.measurements)
    ident = "" if folder is None else archive_id(out)
    reports: dict[str, Any] = {}
    error: str | None = None
    entries: list[str | ExternalLocalizer] = [*task.methods, *task.localizers]
    before: dict[str, EntryResult | None] = {}
    for entry in entries:
        name = entry if isinstance(entry, str) else entry.name
        before[name] = None if folder is None else load(folder, task.scenario, name, ident)
    start = time.perf_counter()
    todo = [m for m in task.methods if before[m] is None]
    keys, ran = reuse.recall(out, todo, seed=task.seed, reference_date=task.reference_date)
    ran |= reuse.remembered(keys, out, _run_methods(task, out, [m for m in todo if m not in ran]))
    times["localize"] += time.perf_counter() - start
    for entry in entries:
        name = entry if isinstance(entry, str) else entry.name
        done = before[name]
        if done is not None:  # measured by an earlier, interrupted run
            reports[name] = done.report
            continue
        key = keys.get(entry) if isinstance(entry, str) else None
        scored, why, run = _measure(task, out, entry, ran, times, key)
        reports[name] = None if scored is None else scored.report
        error = error or why
        if folder is not None:
            result = EntryResult(
                scenario=task.scenario,
                entry=name,
                report=reports[name],
                error=why,
                localize_wall_s=None if run is None else round(run.wall_s, 3),
                frames_per_s=None if run is None else round(run.frames_per_s, 1),
            )
            save(folder, result, ident, None if scored is None else scored.h_err_m)
    return reports, error


@contextlib.contextmanager
def _work_folder(task: RunTask, out: Path) -> Iterator[Path]:
    """A working folder beside the run's archive, holding the run's plan (a worker may not
    see the spec's folder; the path given is the plan's): removed when the block ends. Its
    name is fixed, so a run killed inside it (a killed sweep, a dead worker) leaves it in the
    sweep's own folder, not in /tmp, and the run's next attempt takes it over."""
    folder = out.parent / f".work-{task.id}"
    if folder.exists():
        shutil.rmtree(folder)
    folder.mkdir(parents=True)
    plan = folder / task.plan_name
    plan.write_bytes(task.plan_text)
    try:
        yield plan
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _run_external(task: RunTask, out: Path, localizer: ExternalLocalizer) -> str | None:
    """Fly the run again in lockstep with the localizer program on a free loopback port;
    its ``estimates/NAME.csv`` into the run's archive. None, or why it failed."""
    with _work_folder(task, out) as plan:
        flight = plan.parent / "flight"
        argv = [a for a in task.argv if not a.startswith("--zenoh")]
        log_path = out / f"{localizer.name}.log"
        why = fly_in_lockstep(plan, argv, flight, localizer, log_path)
        if why is not None:
            return f"{why} (log: {log_path.name})"
        if not same_flight(flight, out):
            return "the lockstep flight differs from the run's (trajectory.csv)"
        adopt_estimates(flight, out, localizer.name)
    return None


def _keep(out: Path, keep: str) -> None:
    """``frames``: the per-frame tables, estimates and summaries, no images; ``none``:
    estimates and summaries only."""
    if keep == "all" or not out.is_dir():
        return

    for path in out.iterdir():
        if path.name in (ESTIMATES_DIR, SUMMARY_JSON):
            continue
        if keep == "frames" and path.suffix.lower() != ".jpg":
            continue
        if path.is_dir():
            shutil.rmtree(path)
        else:
            path.unlink()


def _fresh_folder(task: RunTask) -> Path:
    """The run's folder, emptied: what a killed sweep left of it is done again from the start."""
    out = Path(task.archive)
    if out.exists():
        shutil.rmtree(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def _finish(
    task: RunTask,
    summary: dict[str, Any] | None,
    error: str | None,
    times: dict[str, float],
    flying_s: float,
) -> dict[str, Any]:
    """Localize and score a flown run (nothing after a failed flight), keep what ``--keep``
    says; its row. ``flying_s``: the run's share of the flying, before this."""
    start = time.perf_counter()
    reports: dict[str, Any] = {}
    out = Path(task.archive)
    if error is None:
        try:
            if task.methods or task.localizers:
                reports, error = _localize(task, out, times)
            _keep(out, task.keep)
        except AirSitlError as err:
            error = _one_line(err)
        except Exception as err:  # a bug in one run must not stop the others; its line says which
            error = _one_line(err)
    row: dict[str, Any] = _finite(
        {
            "id": task.id,
            "options": task.options,
            "summary": summary,
            "eval": reports,
            "error": error,
            "wall_s": round(flying_s + time.perf_counter() - start, 3),
            "time_s": {k: round(v, 3) for k, v in times.items()},
            "host": socket.gethostname(),
            "archive": task.archive_label,
            "reference_date": task.reference_date,
        }
    )
    return row


def _new_times() -> dict[str, float]:
    # Where the run's wall time went: the flight (its share of one flown for several dates),
    # the rendering and archive writing of its own date, the methods and localizers, the
    # scoring. Nothing flies over a reused archive.
    return {"fly": 0.0, "render": 0.0, "localize": 0.0, "eval": 0.0}


def execute(task: RunTask) -> dict[str, Any]:
    """Fly, localize and score one run; its row (errors included, never raised)."""
    start = time.perf_counter()
    summary: dict[str, Any] | None = None
    error: str | None = None
    times = _new_times()
    own = OwnTime()
    try:
        if task.reuse:
            summary = _row_summary(_read_summary(Path(task.archive)), task.plan_label)
        else:
            out = _fresh_folder(task)
            with _work_folder(task, out) as plan:
                summary = _row_summary(_fly(task, plan, own), task.plan_label)
    except Exception as err:  # AirSitlError: its message; a bug in one run: its type too
        error = _one_line(err)
    flying_s = time.perf_counter() - start
    if not task.reuse:
        times["render"] = own.seconds
        times["fly"] = max(0.0, flying_s - own.seconds)
    return _finish(task, summary, error, times, flying_s)


def execute_group(group: Sequence[RunTask]) -> list[dict[str, Any]]:
    """The rows of runs that differ only in the map date (:mod:`.groups`), flown once for all
    their dates (:func:`~air_sitl.recording.dates.record_dates`: each archive the bytes of
    flying its date alone), then each localized and scored. A run's ``fly`` is its share of
    the flight (the group's flying less every date's own time, split equally), its
    ``render`` its own date's camera and archive. One run, runs that turn out not to share a
    flight, or a shared flight that failed: each flown on its own (:func:`execute`), so that
    each row says why it failed and the others go on."""
    if len(group) < 2:
        return [execute(task) for task in group]
    start = time.perf_counter()
    clocks = [OwnTime() for _ in group]
    shared = False
    try:
        outs = [_fresh_folder(task) for task in group]
        with _work_folder(group[0], outs[0]) as plan:
            requests = [_request(t, plan, c) for t, c in zip(group, clocks, strict=True)]
            shared = shares_flight(requests)
            if shared:
                record_dates(requests)
            for bus in (r.bus for r in requests if r.bus is not None):  # none when shared
                with bus:
                    pass
        summaries = [_row_summary(_read_summary(Path(t.archive)), t.plan_label) for t in group]
    except Exception:  # a date's map that cannot open, a bug: each run alone says which
        shared = False
    flying_s = time.perf_counter() - start
    if not shared:  # each run on its own, the time tried first shared among their rows
        rows = [execute(task) for task in group]
        for row in rows:
            row["wall_s"] = round(row["wall_s"] + flying_s / len(group), 3)
            row["time_s"]["fly"] = round(row["time_s"]["fly"] + flying_s / len(group), 3)
        return rows
    own_s = sum(c.seconds for c in clocks)
    share_s = max(0.0, flying_s - own_s) / len(group)
    rows = []
    for task, clock, summary in zip(group, clocks, summaries, strict=True):
        times = _new_times()
        times["fly"], times["render"] = share_s, clock.seconds
        rows.append(_finish(task, summary, None, times, share_s + clock.seconds))
    return rows
