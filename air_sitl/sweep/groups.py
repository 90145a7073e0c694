"""Runs of a sweep that differ only in the map date, grouped to fly once (issue 34).

Runs whose options are equal but for ``map-date`` fly the same trajectory when nothing closes
the loop on the imagery (:func:`~air_sitl.recording.dates.open_loop`: a camera archive, no
``--nav-aid``, no bus) and no localizer program answers their frames in lockstep (the SPEC's
``localizers``): such runs are one task, flown once with every date rendered from the same
samples (:func:`~air_sitl.sweep.run.execute_group`), each archive byte-identical to flying its
date alone. Only the runs still to do are grouped: a group partly done before (``--resume``)
flies again for the dates it misses, not the others.

Groups come longest first (``-j N``: the workers finish together): a group's cost is taken as
its plan's forecast frames (:mod:`air_sitl.mission.forecast`) times its runs. With fewer
groups than workers, the largest groups are split until every worker has a task.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path

from air_sitl.bus.args import bus_options_from_args
from air_sitl.errors import AirSitlError
from air_sitl.mission.forecast import capture_forecast
from air_sitl.mission.plan_file import load_mission
from air_sitl.options import flight_options_from_args
from air_sitl.recording.dates import open_loop
from air_sitl.runner import home_of
from air_sitl.sweep.run import RunTask
from air_sitl.sweep.spec import fly_parser

DATE_KEY = "map-date"

Group = tuple[RunTask, ...]


def flies_open_loop(task: RunTask) -> bool:
    """Whether the run's flight cannot depend on its imagery (so another date may share it)."""
    if task.reuse or task.localizers:
        return False
    args = fly_parser().parse_args([task.plan_path, *task.argv])
    options = flight_options_from_args(args)
    bus = bus_options_from_args(args).enabled
    return open_loop(options, camera=not args.no_camera, bus=bus)


def _key(task: RunTask) -> tuple[str, str]:
    others = {k: v for k, v in task.options.items() if k != DATE_KEY}
    return task.plan_path, json.dumps(others, sort_keys=True)


def _frames(task: RunTask, cache: dict[tuple[str, str], int]) -> int:
    """The run's forecast capture frames (0 when the plan cannot be read here: the run
    says why when it flies)."""
    args = fly_parser().parse_args([task.plan_path, *task.argv])
    try:
        options = flight_options_from_args(args)
        key = (task.plan_path, f"{options.air_start} {options.max_sim_time_s}")
        if key not in cache:
            mission = load_mission(Path(task.plan_path))
            forecast = capture_forecast(
                mission,
                home_of(mission),
                air_start=options.air_start,
                max_sim_time_s=options.max_sim_time_s,
            )
            cache[key] = forecast.frames
    except (AirSitlError, OSError):
        return 0
    return cache[key]


def group_tasks(tasks: Sequence[RunTask], workers: int = 1) -> list[Group]:
    """``tasks`` as groups (one run each, or the dates of one flight), longest first. Fewer
    groups than ``workers``: the largest are split in two until each worker has one (a second
    flight costs less than an idle core)."""
    groups: dict[tuple[str, str], list[RunTask]] = {}
    alone: list[list[RunTask]] = []
    for task in tasks:
        if flies_open_loop(task):
            groups.setdefault(_key(task), []).append(task)
        else:
            alone.append([task])
    every = [*groups.values(), *alone]
    while len(every) < workers and (big := max(every, key=len, default=[])) and len(big) > 1:
        every.remove(big)
        every += [big[: len(big) // 2], big[len(big) // 2 :]]
    cache: dict[tuple[str, str], int] = {}
    place = {task.id: n for n, task in enumerate(tasks)}
    every.sort(key=lambda g: (-_frames(g[0], cache) * len(g), place[g[0].id]))
    return [tuple(g) for g in every]
