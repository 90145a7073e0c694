"""One flight recorded into the archives of several map dates (issue 34).

Runs that differ only in the map date fly the same trajectory when nothing closes the loop
on the imagery (no aid from the camera, no lockstep bus): the flight does not depend on
what the camera sees. ``record_dates`` flies it once and renders each date's frames from
the same samples: every archive gets its own camera (its date's map, the same camera seed),
writer, trajectory and checks, fed the very samples and frame indices a flight of its own
would have fed them, so its bytes are those of flying that date alone (summary.json's wall
time aside, which no two flights share).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

from air_sitl.builder import FlightSetup, build_flight
from air_sitl.clock import NS_PER_S
from air_sitl.dataset.air_schema import TRAJECTORY_CSV
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
from air_sitl.recording.timing import timed_sinks, timed_source
from air_sitl.sinks import FlightResult, FrameSource, Sink
from air_sitl.state import CameraFrame, SimSample


@dataclass(frozen=True, slots=True)
class _Dated:
    """A frame of one date's camera (``slot``: the date's place in the request list)."""

    slot: int
    frame: CameraFrame


class _DatesCamera:
    """Every date's camera behind one FrameSource: each tick is rendered by all of them."""

    def __init__(self, sources: Sequence[FrameSource]) -> None:
        self._sources = list(sources)

    def submit(self, sample: SimSample, index: int) -> None:
        for source in self._sources:
            source.submit(sample, index)

    def ready(self) -> list[_Dated]:
        return [_Dated(k, f) for k, s in enumerate(self._sources) for f in s.ready()]

    def flush(self) -> list[_Dated]:
        return [_Dated(k, f) for k, s in enumerate(self._sources) for f in s.flush()]

    def close(self) -> None:
        for source in self._sources:
            source.close()


class _DateSinks:
    """One date's sinks: every sample, and the frames of that date's camera only."""

    def __init__(self, slot: int, sinks: Sequence[Sink]) -> None:
        self._slot = slot
        self._sinks = list(sinks)

    def on_sample(self, sample: SimSample) -> None:
        for sink in self._sinks:
            sink.on_sample(sample)

    def on_frame(self, frame: CameraFrame) -> None:
        dated: Any = frame  # a _Dated: what _DatesCamera delivers
        if dated.slot == self._slot:
            for sink in self._sinks:
                sink.on_frame(dated.frame)

    def close(self, result: FlightResult) -> None:
        for sink in self._sinks:
            sink.close(result)


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
    setup = requests[0].setup
    options = setup.options
    sides: list[ArchiveSide] = []
    trajectories: list[TrajectoryWriter] = []
    routers: list[Sink] = []
    try:
        for slot, r in enumerate(requests):
            side = open_archive(
                r.setup, r.out, resume=False, overwrite=r.overwrite, io_thread=r.io_thread
            )
            sides.append(side)
            kind = NavTrajectoryWriter if options.nav == "ekf" else TrajectoryWriter
            trajectories.append(kind(r.out / TRAJECTORY_CSV))
            assert side.writer is not None
            router = _DateSinks(slot, [*side.sinks, trajectories[-1], side.writer])
            routers.extend(timed_sinks([router], r.own_time))  # each date's own time apart
        cameras = [timed_source(s.camera, r.own_time) for s, r in zip(sides, requests, strict=True)]
        camera = _DatesCamera([c for c in cameras if c is not None])
        flight = build_flight(setup, sinks=routers, camera=camera)  # type: ignore[arg-type]
    except BaseException:
        for side in sides:
            side.abort()
        raise
    result = flight.run(
        stop=lambda sample: sample.autopilot.mission_completed or flight.stats.crashed is not None,
        max_sim_time_ns=int(options.max_sim_time_s * NS_PER_S),
        progress=progress,
    )
    results = []
    for r, side, trajectory in zip(requests, sides, trajectories, strict=True):
        trajectory.raise_if_failed()
        summary = dict(result.summary)
        summary["plan"] = r.summary_plan if r.summary_plan is not None else str(r.setup.plan)
        manifest = finish_archive(side, summary, flight.counters.capture_ticks, r.own_time)
        results.append(
            RecordingResult(
                out=r.out, summary=side.summary, manifest=manifest, resumed_from_frame=0
            )
        )
    return results
