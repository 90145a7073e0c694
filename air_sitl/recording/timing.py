"""Where a recording's wall time goes: its archive's own parts, apart from the flight.

A recording asked for it (``RecordingRequest.own_time``) adds to :class:`OwnTime` the wall
seconds spent in its camera (render, noise, JPEG: :class:`TimedSource`) and in its archive's
sinks (the checks, ``trajectory.csv``, the writer: :class:`TimedSinks`); the rest of the flight
is the flight's. Dates flown once (:mod:`.dates`) each have their own: what one more date
costs. The wrappers only measure: every call is passed on as it came, in the same order.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass

from air_sitl.sinks import FlightResult, FrameSource, Sink
from air_sitl.state import CameraFrame, SimSample


@dataclass(slots=True)
class OwnTime:
    """Wall seconds of one archive's own parts (its camera and its sinks)."""

    seconds: float = 0.0


class TimedSource:
    """A FrameSource whose calls add their wall time to ``clock``."""

    def __init__(self, source: FrameSource, clock: OwnTime) -> None:
        self._source = source
        self._clock = clock

    def submit(self, sample: SimSample, index: int) -> None:
        start = time.perf_counter()
        self._source.submit(sample, index)
        self._clock.seconds += time.perf_counter() - start

    def ready(self) -> list[CameraFrame]:
        start = time.perf_counter()
        frames = self._source.ready()
        self._clock.seconds += time.perf_counter() - start
        return frames

    def flush(self) -> list[CameraFrame]:
        start = time.perf_counter()
        frames = self._source.flush()
        self._clock.seconds += time.perf_counter() - start
        return frames

    def close(self) -> None:
        self._source.close()


class TimedSinks:
    """Sinks called in order as one sink, their wall time added to ``clock``."""

    def __init__(self, sinks: Sequence[Sink], clock: OwnTime) -> None:
        self._sinks = list(sinks)
        self._clock = clock

    def on_sample(self, sample: SimSample) -> None:
        start = time.perf_counter()
        for sink in self._sinks:
            sink.on_sample(sample)
        self._clock.seconds += time.perf_counter() - start

    def on_frame(self, frame: CameraFrame) -> None:
        start = time.perf_counter()
        for sink in self._sinks:
            sink.on_frame(frame)
        self._clock.seconds += time.perf_counter() - start

    def close(self, result: FlightResult) -> None:
        start = time.perf_counter()
        for sink in self._sinks:
            sink.close(result)
        self._clock.seconds += time.perf_counter() - start


def timed_sinks(sinks: Sequence[Sink], clock: OwnTime | None) -> list[Sink]:
    """``sinks`` as they are without a clock, else as one timed sink (none: none)."""
    if clock is None or not sinks:
        return list(sinks)
    return [TimedSinks(sinks, clock)]


def timed_source(source: FrameSource | None, clock: OwnTime | None) -> FrameSource | None:
    """``source`` timed into ``clock`` (as it is without a clock or a source)."""
    if clock is None or source is None:
        return source
    return TimedSource(source, clock)
