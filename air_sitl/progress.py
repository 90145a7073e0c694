"""Terminal progress: a flight's bar and summary, many jobs' lines (presentation only)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import IO, Any

from air_sitl.clock import NS_PER_S
from air_sitl.mission.items import Mission
from air_sitl.recording.batch import Outcome
from air_sitl.runner import Flight
from air_sitl.state import SimSample


class InPlaceLine:
    """One terminal line rewritten in place: ``label [#####.....] text``."""

    def __init__(self, label: str, stream: IO[str], *, label_width: int, width: int = 30) -> None:
        self.label = label
        self.stream = stream
        self.label_width = label_width
        self.width = width

    def draw(self, frac: float, text: str) -> None:
        """Redraw the line with a bar ``frac`` full."""
        filled = int(frac * self.width)
        bar = "#" * filled + "." * (self.width - filled)
        self.stream.write(f"\r{self.label:>{self.label_width}} [{bar}] {text}")
        self.stream.flush()

    def finish(self) -> None:
        """End the progress line."""
        self.stream.write("\n")
        self.stream.flush()


class ProgressBar(InPlaceLine):
    """A flight's line: mission progress, simulated time, mode, frames."""

    def __init__(self, mission: Mission, stream: IO[str], width: int = 30) -> None:
        super().__init__(mission.name or "flight", stream, label_width=8, width=width)
        self.total = max(1, len(mission.items))

    def update(self, sample: SimSample, flight: Flight) -> None:
        """Redraw from the latest sample."""
        seq = max(0, sample.autopilot.current_seq)
        t = sample.state.sim_time_ns / NS_PER_S
        self.draw(
            min(1.0, seq / self.total),
            f"item {seq}/{self.total} sim {t:7.0f} s  {sample.autopilot.mode.value:<8} "
            f"frames {flight.stats.capture_frames:6d}",
        )


def _metres(value: object) -> str:
    """``12.3 m``, or ``n/a`` when nothing was measured (null in summary.json)."""
    return f"{value:.1f} m" if isinstance(value, int | float) else "n/a"


def print_summary(summary: dict[str, Any], out: Path, stream: IO[str]) -> None:
    """The one-screen summary after a flight."""
    done = "completed" if summary["mission_completed"] else "NOT completed"
    crashed = summary.get("crashed")
    if crashed:
        done = (
            f"NOT completed: CRASHED at {crashed['sim_time_s']:.1f} s, "
            f"{crashed['lat_deg']:.6f}, {crashed['lon_deg']:.6f}: {crashed['reason']}"
        )
    elif not summary["mission_completed"]:
        done = "NOT completed: the time limit (--max-sim-time) ended the flight"
    elif summary.get("landed"):
        done = "completed, landed"
    lines = [
        f"mission {summary.get('plan', '')}: {done}",
        f"  waypoints        {summary['waypoints_reached']}/{summary['waypoints_total']}",
        f"  capture          {summary['capture_frames']} frames, "
        f"{summary['capture_distance_m']:.0f} m",
        f"  max cross-track  {_metres(summary.get('max_cross_track_m'))}",
        f"  max alt error    {_metres(summary.get('max_alt_error_m'))}",
        f"  time             {summary['sim_time_s']:.0f} s simulated in "
        f"{summary['wall_time_s']:.1f} s wall ({summary['realtime_factor']}x)",
        f"  output           {out}",
    ]
    stream.write("\n".join(lines) + "\n")


class JobsDisplay:
    """One progress line per job plus an overall one (redrawn in place on a terminal)."""

    def __init__(self, names: list[str], expected: dict[str, int], stream: IO[str], tty: bool):
        self.names = names
        self.expected = expected
        self.stream = stream
        self.tty = tty
        self.frames = dict.fromkeys(names, 0)
        self.sim_s = dict.fromkeys(names, 0.0)
        self.state = dict.fromkeys(names, "waiting")
        self.start = time.monotonic()
        self._drawn = 0
        self._last = 0.0

    def _bar(self, done: int, total: int, width: int = 24) -> str:
        frac = min(1.0, done / total) if total > 0 else 0.0
        filled = int(frac * width)
        return f"[{'#' * filled}{'.' * (width - filled)}] {100 * frac:5.1f}%"

    def update(self, name: str, frames: int, sim_s: float) -> None:
        """A progress report from a job."""
        if self.state[name] == "waiting":
            self.state[name] = "flying"
            if not self.tty:
                self.stream.write(f"{name}: flying\n")
        self.frames[name] = frames
        self.sim_s[name] = sim_s
        self.draw()

    def done(self, outcome: Outcome) -> None:
        """A job finished."""
        name = outcome.name
        if outcome.error:
            self.state[name] = "FAILED"
            line = f"{name}: FAILED: {outcome.error}"
        else:
            self.frames[name] = outcome.images
            ok = "done" if outcome.mission_completed else "done (mission NOT completed)"
            self.state[name] = ok
            line = (
                f"{name}: {ok}: {outcome.images} frames, {outcome.distance_m:.0f} m, "
                f"{outcome.sim_time_s:.0f} s simulated in {outcome.wall_s:.0f} s"
            )
        if not self.tty:
            finished = sum(1 for s in self.state.values() if s not in ("waiting", "flying"))
            self.stream.write(f"[{finished}/{len(self.names)}] {line}\n")
            self.stream.flush()
        self.draw(force=True)

    def draw(self, *, force: bool = False) -> None:
        """Redraw every line (terminal only, at most 10 times a second)."""
        if not self.tty:
            return
        now = time.monotonic()
        if not force and now - self._last < 0.1:
            return
        self._last = now
        lines = []
        for name in self.names:
            lines.append(
                f"{name:>16} {self._bar(self.frames[name], self.expected.get(name, 0))} "
                f"{self.frames[name]:6d} frames  sim {self.sim_s[name]:6.0f} s  {self.state[name]}"
            )
        total = sum(self.frames.values())
        total_expected = sum(self.expected.get(n, 0) for n in self.names)
        wall = now - self.start
        lines.append(
            f"{'overall':>16} {self._bar(total, total_expected)} {total:6d} frames  "
            f"{wall:6.0f} s wall  {total / wall if wall > 0 else 0:5.0f} frames/s"
        )
        if self._drawn:
            self.stream.write(f"\x1b[{self._drawn}F")
        self.stream.write("\n".join(f"{line}\x1b[K" for line in lines) + "\n")
        self.stream.flush()
        self._drawn = len(lines)
