"""Terminal progress bar and the one-screen flight summary (presentation only)."""

from __future__ import annotations

from pathlib import Path
from typing import IO, Any

from air_sitl.clock import NS_PER_S
from air_sitl.mission.items import Mission
from air_sitl.runner import Flight
from air_sitl.state import SimSample


class ProgressBar:
    """One line, rewritten in place: mission progress, simulated time, frames, speed."""

    def __init__(self, mission: Mission, stream: IO[str], width: int = 30) -> None:
        self.total = max(1, len(mission.items))
        self.stream = stream
        self.width = width
        self.label = mission.name or "flight"

    def update(self, sample: SimSample, flight: Flight) -> None:
        """Redraw from the latest sample."""
        seq = max(0, sample.autopilot.current_seq)
        frac = min(1.0, seq / self.total)
        filled = int(frac * self.width)
        t = sample.state.sim_time_ns / NS_PER_S
        self.stream.write(
            f"\r{self.label:>8} [{'#' * filled}{'.' * (self.width - filled)}] "
            f"item {seq}/{self.total} sim {t:7.0f} s  {sample.autopilot.mode.value:<8} "
            f"frames {flight.stats.capture_frames:6d}"
        )
        self.stream.flush()

    def finish(self) -> None:
        """End the progress line."""
        self.stream.write("\n")
        self.stream.flush()


def print_summary(summary: dict[str, Any], out: Path, stream: IO[str]) -> None:
    """The one-screen summary after a flight."""
    done = "completed" if summary["mission_completed"] else "NOT completed"
    lines = [
        f"mission {summary.get('plan', '')}: {done}",
        f"  waypoints        {summary['waypoints_reached']}/{summary['waypoints_total']}",
        f"  capture          {summary['capture_frames']} frames, "
        f"{summary['capture_distance_m']:.0f} m",
        f"  max cross-track  {summary['max_cross_track_m']:.1f} m",
        f"  max alt error    {summary['max_alt_error_m']:.1f} m",
        f"  time             {summary['sim_time_s']:.0f} s simulated in "
        f"{summary['wall_time_s']:.1f} s wall ({summary['realtime_factor']}x)",
        f"  output           {out}",
    ]
    stream.write("\n".join(lines) + "\n")
