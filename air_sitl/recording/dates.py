"""One flight recorded into the archives of several map dates (issue 34).

Runs that differ only in the map date fly the same trajectory when nothing closes the loop
on the imagery (no aid from the camera, no lockstep bus): the flight does not depend on
what the camera sees. ``record_dates`` flies it once and renders each date's frames from
the same samples: every archive gets its own camera (its date's map, the same camera seed),
writer, trajectory and checks, fed the very samples and frame indices a flight of its own
would have fed them, so its bytes are those of flying that date alone (summary.json's wall
time aside, which no two flights share).

What the dates share is done once: a tick's frames of every date are rendered in one job on
one pool of threads, with one geometry and one noise slice when the maps share a grid
(:mod:`air_sitl.camera.same_grid`); a sample's ``imu.csv`` line (200 a simulated second) is
formatted once, each date's file written from it.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

from air_sitl.builder import FlightSetup, build_flight
from air_sitl.clock import NS_PER_S
from air_sitl.dataset.air_schema import TRAJECTORY_CSV, imu_row
from air_sitl.dataset.writer import DatasetWriter
from air_sitl.flightlog import NavTrajectoryWriter, TrajectoryWriter
from air_sitl.options import FlightOptions
from air_sitl.recording.archive import (
    ArchiveSide,
    ProgressFn,
    RecordingRequest,
    RecordingResult,
    finish_archive,
    open_archive,
)
from air_sitl.recording.timing import OwnTime
from air_sitl.sinks import FlightResult, Sink
from air_sitl.state import CameraFrame, SimSample

if TYPE_CHECKING:  # OpenCV loads with the first camera
    from air_sitl.camera.same_grid import GridCamera


@dataclass(frozen=True, slots=True)
class _Dated:
    """A frame of one date's camera (``slot``: the date's place in the request list)."""

    slot: int
    frame: CameraFrame


def _spend(clocks: Sequence[OwnTime], start: float) -> None:
    """The wall time since ``start`` shared evenly among the dates' ``clocks``."""
    if clocks:
        share = (time.perf_counter() - start) / len(clocks)
        for clock in clocks:
            clock.seconds += share


class _DatesCamera:
    """Every date's camera behind one FrameSource: each tick rendered for all of them in one
    job (:class:`~air_sitl.camera.same_grid.GridCamera`), delivered date by date; its time
    on the simulation thread shared among the dates' clocks."""

    def __init__(self, camera: GridCamera, clocks: Sequence[OwnTime]) -> None:
        self._camera = camera
        self._clocks = list(clocks)

    def submit(self, sample: SimSample, index: int) -> None:
        start = time.perf_counter()
        self._camera.submit(sample, index)
        _spend(self._clocks, start)

    def ready(self) -> list[_Dated]:
        start = time.perf_counter()
        ticks = self._camera.ready()
        _spend(self._clocks, start)
        return [_Dated(k, f) for tick in ticks for k, f in enumerate(tick)]

    def flush(self) -> list[_Dated]:
        start = time.perf_counter()
        ticks = self._camera.flush()
        _spend(self._clocks, start)
        return [_Dated(k, f) for tick in ticks for k, f in enumerate(tick)]

    def close(self) -> None:
        self._camera.close()


@dataclass(frozen=True, slots=True)
class _DateSinks:
    """One date's sinks: its archive's checks, its trajectory and its writer."""

    checks: list[Sink]
    trajectory: TrajectoryWriter
    writer: DatasetWriter
    clock: OwnTime | None

    @property
    def sinks(self) -> list[Sink]:
        return [*self.checks, self.trajectory, self.writer]


class _DatesSinks:
    """Every date's sinks as one sink. A sample's ``imu.csv`` line, which does not depend on
    the imagery, is formatted once and handed to each date's writer, the same bytes as each
    formatting its own (``trajectory.csv``'s rows are made by a compiled call, about 1 us a
    row: each date makes its own); a frame goes to its date's sinks only."""

    def __init__(self, dates: Sequence[_DateSinks]) -> None:
        self._dates = list(dates)
        self._clocks = [d.clock for d in self._dates if d.clock is not None]

    def on_sample(self, sample: SimSample) -> None:
        start = time.perf_counter()
        line = imu_row(sample.imu)
        for date in self._dates:
            for check in date.checks:
                check.on_sample(sample)
            date.trajectory.on_sample(sample)
            date.writer.on_sample_line(sample, line)
        _spend(self._clocks, start)

    def on_frame(self, frame: CameraFrame) -> None:
        dated: Any = frame  # a _Dated: what _DatesCamera delivers
        date = self._dates[dated.slot]
        start = time.perf_counter()
        f: CameraFrame = dated.frame
        for check in date.checks:
            check.on_frame(f)
        date.trajectory.on_frame(f)
        date.writer.on_frame(f)
        if date.clock is not None:
            date.clock.seconds += time.perf_counter() - start

    def close(self, result: FlightResult) -> None:
        for date in self._dates:
            start = time.perf_counter()
            for sink in date.sinks:
                sink.close(result)
            if date.clock is not None:
                date.clock.seconds += time.perf_counter() - start


def open_loop(options: FlightOptions, *, camera: bool, bus: bool) -> bool:
    """Whether a flight's trajectory cannot depend on its imagery, so that another map date
    changes its frames only: a camera archive, no aid from the camera (``--nav-aid``) and no
    bus (a lockstep localizer, or anything answering frames over it). The one rule of
    flying dates once (:func:`shares_flight`; the sweep groups its runs by it)."""
    return camera and not bus and options.nav_aid is None


def _but_the_date(setup: FlightSetup, date: str | None) -> FlightSetup:
    """``setup`` at map date ``date``, its open map left out (each date's map is its own)."""
    return replace(setup, map=replace(setup.map, date=date), map_source=None)


def shares_flight(requests: Sequence[RecordingRequest]) -> bool:
    """Whether ``requests`` may be flown once: new camera archives of open-loop flights
    (:func:`open_loop`) whose setups are equal but for the map date (and its open map)."""
    if len(requests) < 2:
        return False
    first = _but_the_date(requests[0].setup, requests[0].setup.map.date)
    for r in requests:
        if not open_loop(r.setup.options, camera=r.setup.camera is not None, bus=r.bus is not None):
            return False
        if r.resume and r.out.is_dir() and any(r.out.iterdir()):
            return False
        if _but_the_date(r.setup, first.map.date) != first:
            return False
    return True


def record_dates(
    requests: Sequence[RecordingRequest], *, progress: ProgressFn | None = None
) -> list[RecordingResult]:
    """Fly once and record every request's archive (``shares_flight(requests)`` holds)."""
    assert shares_flight(requests), "record_dates: the requests differ in more than the date"
    from air_sitl.camera.bridge import CameraBridge
    from air_sitl.camera.same_grid import GridCamera

    setup = requests[0].setup
    options = setup.options
    sides: list[ArchiveSide] = []
    dates: list[_DateSinks] = []
    grid: GridCamera | None = None
    try:
        for r in requests:
            side = open_archive(
                r.setup, r.out, resume=False, overwrite=r.overwrite, io_thread=r.io_thread
            )
            sides.append(side)
            kind = NavTrajectoryWriter if options.nav == "ekf" else TrajectoryWriter
            assert side.writer is not None
            trajectory = kind(r.out / TRAJECTORY_CSV)
            dates.append(_DateSinks(side.sinks, trajectory, side.writer, r.own_time))
        bridges: list[CameraBridge] = []
        for side in sides:
            assert isinstance(side.camera, CameraBridge)
            bridges.append(side.camera)
        grid = GridCamera(bridges, workers=setup.render_workers)
        for side in sides:
            side.camera = None  # the grid camera closes them
        clocks = [r.own_time for r in requests if r.own_time is not None]
        camera = _DatesCamera(grid, clocks)
        sinks: list[Sink] = [_DatesSinks(dates)]
        flight = build_flight(setup, sinks=sinks, camera=camera)  # type: ignore[arg-type]
    except BaseException:
        if grid is not None:
            grid.close()
        for side in sides:
            side.abort()
        unflown = FlightResult(mission_completed=False, sim_time_ns=0, wall_time_s=0.0)
        for date in dates:
            date.trajectory.close(unflown)
        raise
    result = flight.run(
        stop=lambda sample: sample.autopilot.mission_completed or flight.stats.crashed is not None,
        max_sim_time_ns=int(options.max_sim_time_s * NS_PER_S),
        progress=progress,
    )
    results = []
    for r, side, date in zip(requests, sides, dates, strict=True):
        date.trajectory.raise_if_failed()
        summary = dict(result.summary)
        summary["plan"] = r.summary_plan if r.summary_plan is not None else str(r.setup.plan)
        manifest = finish_archive(side, summary, flight.counters.capture_ticks, r.own_time)
        results.append(
            RecordingResult(
                out=r.out, summary=side.summary, manifest=manifest, resumed_from_frame=0
            )
        )
    return results
