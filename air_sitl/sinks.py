"""What a flight emits, and the Sink protocol every consumer implements.

Data flows one way: clock -> flight model -> autopilot -> sensors -> sinks. Sinks (trajectory
writer, dataset logger, MAVLink telemetry, zenoh publisher) never import each other; the runner
calls them from the simulation thread, in order, and a sink that does I/O hands work to its own
thread through a queue if it must not block.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from air_sitl.state import CameraFrame, SimSample


@dataclass(frozen=True, slots=True, kw_only=True)
class FlightResult:
    """How a flight ended; given to every sink's ``close``."""

    mission_completed: bool
    sim_time_ns: int
    wall_time_s: float
    summary: dict[str, Any] = field(default_factory=dict)  # the summary.json content


class Sink(Protocol):
    """A consumer of simulation output."""

    def on_sample(self, sample: SimSample) -> None:
        """Called at every physics step (200 Hz of simulated time)."""
        ...

    def on_frame(self, frame: CameraFrame) -> None:
        """Called for every camera frame, in index order: those of the capture window, or of
        the whole flight when the camera stays on for an aid (outside the window
        ``frame.sample.camera`` has no ``capture_index``: not for an archive)."""
        ...

    def close(self, result: FlightResult) -> None:
        """Called once at the end of the flight (also after an error, with what is known)."""
        ...


class NullSink:
    """Base class with no-op methods: subclass and override what you need."""

    def on_sample(self, sample: SimSample) -> None:
        """Ignore the sample."""

    def on_frame(self, frame: CameraFrame) -> None:
        """Ignore the frame."""

    def close(self, result: FlightResult) -> None:
        """Nothing to close."""


class FrameSource(Protocol):
    """Turns physics samples at camera ticks into camera frames, possibly in parallel.

    ``submit`` may return before the frame is rendered; ``ready`` returns the frames completed
    so far in index order (never skipping one); ``flush`` waits for all submitted frames.
    """

    def submit(self, sample: SimSample, index: int) -> None:
        """Queue the frame ``index`` taken at ``sample``."""
        ...

    def ready(self) -> list[CameraFrame]:
        """Frames completed since the last call, in index order, without waiting."""
        ...

    def flush(self) -> list[CameraFrame]:
        """Wait for every submitted frame and return the remaining ones in order."""
        ...

    def close(self) -> None:
        """Release threads and map handles."""
        ...
