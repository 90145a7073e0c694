"""Where the runs of a sweep execute: a local process pool (default) or Ray tasks.

Both take groups of :class:`~air_sitl.sweep.run.RunTask` objects (one run, or the map dates
of one flight: :mod:`~air_sitl.sweep.groups`), one group a task, and hand each finished row to
``on_row`` in the driver, in completion order; the driver alone writes ``results.jsonl``.

- :class:`PoolExecutor`: ``-j N`` spawned worker processes (forked workers can hang on the
  threads numpy/OpenCV/zenoh start), one thread each for BLAS and OpenCV, a procedural map
  kept per worker, its drawn ground shared by the workers (a folder of the sweep). A worker
  dies with the driver (Linux ``PR_SET_PDEATHSIG``), so a killed sweep leaves no orphan
  writing into a run folder; a worker that dies mid-run (killed, out of memory) is replaced
  and its group tried once more, then its runs recorded as failed.
- :class:`RayExecutor`: the same runs as Ray tasks (``ray`` is the optional extra
  ``air-sitl[ray]``): a local Ray (``--ray``) or a cluster (``--ray ADDRESS``). Each task
  carries its own plan text and seed, each bus takes a free loopback port, rows come back
  small, archives stay on the worker's filesystem at the path the task names.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import socket
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from types import FrameType
from typing import Any

from air_sitl.maps.procedural.shared_tiles import shared_folder
from air_sitl.sweep.errors import SweepError
from air_sitl.sweep.groups import Group
from air_sitl.sweep.run import (
    THREAD_ENV,
    RunTask,
    execute_group,
    pin_threads,
    share_ground_through,
)
from air_sitl.workers import die_with_parent

OnRow = Callable[[dict[str, Any]], None]
CRASHES_ALLOWED = 1  # a run whose worker died this many times is tried once more, then failed


def _no_interrupt(_signum: int, _frame: FrameType | None) -> None:
    """A worker's SIGINT: nothing (see _init_worker)."""


def _init_worker(shared_ground: Path | None = None) -> None:
    # Ctrl-C reaches the whole process group: the driver alone decides, workers are stopped.
    # A handler that does nothing rather than SIG_IGN: an ignored signal stays ignored in the
    # programs a worker starts (a user's localizer would sit out stop()'s SIGINT until its
    # SIGKILL), a handler goes back to the default in them.
    signal.signal(signal.SIGINT, _no_interrupt)
    die_with_parent()
    pin_threads()
    share_ground_through(shared_ground)


def _crashed_row(task: RunTask, why: str) -> dict[str, Any]:
    """The row of a run whose worker died: every key of a row, its times unknown (null)."""
    return {
        "id": task.id,
        "options": task.options,
        "summary": None,
        "eval": {},
        "error": why,
        "wall_s": None,
        "host": None,
        "archive": task.archive_label,
        "reference_date": task.reference_date,
        "time_s": None,
    }


class PoolExecutor:
    """``jobs`` spawned worker processes; one group per task. Used as a context manager, its
    workers (and their shared ground) serve every ``run`` inside the block: several sweeps
    one after another (bench's map dates) start their workers once, and what a worker keeps
    (maps, :mod:`~air_sitl.sweep.reuse`'s results) serves the later sweeps."""

    def __init__(self, jobs: int) -> None:
        self.workers = jobs
        self._shared_ground: Path | None = None
        self._kept: contextlib.ExitStack | None = None  # inside the block
        self._kept_pool: ProcessPoolExecutor | None = None

    def __enter__(self) -> PoolExecutor:
        self._kept = contextlib.ExitStack()
        self._shared_ground = self._kept.enter_context(shared_folder())
        return self

    def __exit__(self, *exc: object) -> None:
        pool, self._kept_pool = self._kept_pool, None
        if pool is not None:
            pool.shutdown(wait=True)
        kept, self._kept = self._kept, None
        if kept is not None:
            kept.close()

    def _pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker,
            initargs=(self._shared_ground,),
        )

    def run(self, groups: Sequence[Group], on_row: OnRow) -> None:
        """Run every group; ``on_row`` gets each row as it finishes. Ctrl-C stops the workers."""
        saved = {name: os.environ.get(name) for name in THREAD_ENV}
        os.environ.update(dict.fromkeys(THREAD_ENV, "1"))  # inherited by the spawned workers
        try:
            if self._kept is not None:  # the block's workers and ground
                self._run(list(groups), on_row)
            else:  # the workers draw each square of procedural ground once for all of them
                with shared_folder() as self._shared_ground:
                    self._run(list(groups), on_row)
        finally:
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value

    def _run(self, todo: list[Group], on_row: OnRow) -> None:
        crashes: dict[str, int] = {}
        while todo:
            if self._kept is None:
                pool = self._pool()
            else:
                pool = self._kept_pool = self._kept_pool or self._pool()
            futures: dict[Future[list[dict[str, Any]]], Group] = {}
            broken: list[Group] = []
            try:
                futures = {pool.submit(execute_group, group): group for group in todo}
                pending = set(futures)
                while pending:
                    done, pending = wait(pending, return_when=FIRST_COMPLETED)
                    for fut in done:
                        try:
                            rows = fut.result()
                        except BrokenProcessPool:
                            broken.append(futures[fut])
                            continue
                        for row in rows:
                            on_row(row)
            except BaseException:
                self._kept_pool = None
                _terminate(pool)
                raise
            if self._kept is None or broken:  # a broken pool takes no more work
                self._kept_pool = None
                pool.shutdown(wait=True)
            todo = []
            for group in broken:
                key = group[0].id
                crashes[key] = crashes.get(key, 0) + 1
                if crashes[key] > CRASHES_ALLOWED:
                    why = "its worker process died (killed or out of memory)"
                    for task in group:
                        on_row(_crashed_row(task, why))
                else:
                    todo.append(group)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: pending runs cancelled, running workers killed (their run folders
    are done again on resume)."""
    processes = list((getattr(pool, "_processes", None) or {}).values())
    manager = getattr(pool, "_executor_manager_thread", None)
    pool.shutdown(wait=False, cancel_futures=True)
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.kill()
    for proc in processes:
        with contextlib.suppress(Exception):
            proc.join(5)
    # Let the pool's manager thread finish its clean-up now: left running, it closes its
    # wake-up pipe while the interpreter's exit hook (concurrent.futures' _python_exit) writes
    # to it, and Ctrl-C ends in a traceback "OSError: [Errno 9] Bad file descriptor".
    if manager is not None:
        manager.join(5)


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Refuse at once a ``HOST:PORT`` (or ``ray://HOST:PORT``) nothing listens on: Ray itself
    retries for minutes before giving up."""
    host, sep, port = address.removeprefix("ray://").rpartition(":")
    if not sep or not port.isdigit() or not host:
        return  # "auto" and other forms: Ray's own lookup
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s):
            pass
    except OSError as err:
        msg = (
            f"--ray {address}: nothing answers there ({err.strerror or err}); start the head "
            "with `ray start --head` or give its address"
        )
        raise SweepError(msg) from None


def _ray_execute(group: Group) -> list[dict[str, Any]]:
    pin_threads()
    return execute_group(group)


class RayExecutor:
    """The runs as Ray tasks: ``address`` None starts a local Ray of ``num_cpus`` CPUs,
    otherwise joins that cluster (``auto``, ``ray://HOST:10001``, ``HOST:6379``)."""

    def __init__(self, address: str | None, *, num_cpus: int | None = None) -> None:
        self.address = address
        self.num_cpus = num_cpus
        # A local Ray runs this many at once; a cluster's size is not known before it is joined.
        self.workers = (num_cpus or os.cpu_count() or 1) if address is None else 1
        self.init_s = 0.0

    def run(self, groups: Sequence[Group], on_row: OnRow) -> None:
        """Run every group on Ray; ``on_row`` gets each row as it finishes."""
        try:
            import ray  # the optional extra air-sitl[ray]
        except ImportError:
            msg = "--ray: ray is not installed (pip install 'air-sitl[ray]')"
            raise SweepError(msg) from None
        start = time.perf_counter()
        started_here = not ray.is_initialized()
        if started_here:
            try:
                if self.address:
                    _check_reachable(self.address)
                    ray.init(address=self.address, log_to_driver=False)
                else:
                    ray.init(
                        address="local",  # a new local Ray, whatever cluster is running here
                        num_cpus=self.num_cpus or os.cpu_count() or 1,
                        include_dashboard=False,
                        log_to_driver=False,
                    )
            except (ConnectionError, RuntimeError, ValueError) as err:
                where = self.address or "a local Ray"
                msg = f"--ray {where}: cannot connect: {str(err).splitlines()[0]}"
                raise SweepError(msg) from None
        self.init_s = time.perf_counter() - start
        remote = ray.remote(num_cpus=1, max_retries=0)(_ray_execute)
        refs: dict[Any, Group] = {remote.remote(group): group for group in groups}
        pending = list(refs)
        try:
            while pending:
                done, pending = ray.wait(pending, num_returns=1)
                for ref in done:
                    try:
                        rows = ray.get(ref)
                    except ray.exceptions.RayError as err:
                        why = str(err).strip().splitlines()
                        line = why[-1] if why else type(err).__name__
                        rows = [_crashed_row(task, f"Ray: {line}") for task in refs[ref]]
                    for row in rows:
                        on_row(row)
        except BaseException:
            for ref in pending:
                with contextlib.suppress(Exception):
                    ray.cancel(ref, force=True)
            raise
        finally:
            if started_here:
                ray.shutdown()
