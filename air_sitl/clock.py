"""Integer-nanosecond simulation clock with a fixed physics step and optional wall pacing."""

from __future__ import annotations

import time
from dataclasses import dataclass, field

from air_sitl.errors import OptionError

NS_PER_S = 1_000_000_000
PHYSICS_RATE_HZ = 200
CAMERA_RATE_HZ = 50
PHYSICS_STEP_NS = NS_PER_S // PHYSICS_RATE_HZ  # 5 ms
CAMERA_PERIOD_NS = NS_PER_S // CAMERA_RATE_HZ  # 20 ms, exactly 4 physics steps


@dataclass(slots=True)
class SimClock:
    """Simulation time: starts at 0, advances by exactly ``step_ns`` per tick."""

    step_ns: int = PHYSICS_STEP_NS
    now_ns: int = 0

    def tick(self) -> int:
        """Advance one physics step and return the new time."""
        self.now_ns += self.step_ns
        return self.now_ns

    def is_multiple_of(self, period_ns: int) -> bool:
        """True when the current time falls exactly on a multiple of ``period_ns``."""
        return self.now_ns % period_ns == 0


@dataclass(slots=True)
class Pacer:
    """Holds simulated time to ``speed`` x wall-clock time; speed 0 never waits.

    Only for pacing: the wall clock never enters the data.
    """

    speed: float
    _wall_start: float = field(default=0.0, init=False)
    _sim_start_ns: int = field(default=0, init=False)
    _started: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        if not (self.speed >= 0.0) or self.speed == float("inf"):
            msg = f"--speed: {self.speed!r} is not a finite number >= 0 (0 = as fast as possible)"
            raise OptionError(msg)

    def restart(self, sim_time_ns: int) -> None:
        """Re-anchor pacing (after a pause, or when the speed changes)."""
        self._wall_start = time.monotonic()
        self._sim_start_ns = sim_time_ns
        self._started = True

    def wait(self, sim_time_ns: int) -> None:
        """Sleep until wall time has caught up with ``sim_time_ns`` at this speed."""
        if self.speed == 0.0:
            return
        if not self._started:
            self.restart(sim_time_ns)
            return
        due = self._wall_start + (sim_time_ns - self._sim_start_ns) / NS_PER_S / self.speed
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        elif delay < -0.5:
            # Fell far behind (a slow machine or a pause): do not sprint to catch up.
            self.restart(sim_time_ns)
