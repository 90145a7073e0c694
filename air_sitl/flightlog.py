"""The flight core's own records: ``trajectory.csv`` (truth at 50 Hz) and the summary metrics.

Both are fed from the simulation thread. ``FlightStats`` is not a sink: the runner owns it and
hands its summary to every sink in :class:`~air_sitl.sinks.FlightResult`.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import IO, Any

from air_sitl.clock import CAMERA_PERIOD_NS, NS_PER_S
from air_sitl.errors import DatasetError
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import SimSample

TRAJECTORY_COLUMNS = (
    "sim_time_ns",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "north_m",
    "east_m",
    "down_m",
    "qw",
    "qx",
    "qy",
    "qz",
    "vn_m_s",
    "ve_m_s",
    "vd_m_s",
    "p_rad_s",
    "q_rad_s",
    "r_rad_s",
    "airspeed_m_s",
    "mode",
    "mission_seq",
    "capturing",
)


def _row(sample: SimSample) -> str:
    s = sample.state
    a = sample.autopilot
    n, e, d = s.pos_ned_m
    qw, qx, qy, qz = s.q_body_to_ned_wxyz
    vn, ve, vd = s.vel_ned_m_s
    p, q, r = s.rate_frd_rad_s
    return (
        f"{s.sim_time_ns},{s.lat_deg:.9f},{s.lon_deg:.9f},{s.alt_amsl_m:.4f},"
        f"{n:.4f},{e:.4f},{d:.4f},{qw:.8f},{qx:.8f},{qy:.8f},{qz:.8f},"
        f"{vn:.4f},{ve:.4f},{vd:.4f},{p:.6f},{q:.6f},{r:.6f},{s.airspeed_m_s:.4f},"
        f"{a.mode.value},{a.current_seq},{int(a.capturing)}\n"
    )


class TrajectoryWriter(NullSink):
    """Writes truth at 50 Hz over the whole flight to ``trajectory.csv``."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._file: IO[str] = path.open("w", encoding="ascii", newline="")
        except OSError as err:
            msg = f"{path}: cannot write the trajectory: {err.strerror}"
            raise DatasetError(msg) from None
        self._file.write(",".join(TRAJECTORY_COLUMNS) + "\n")
        self._last_flush_ns = 0

    def on_sample(self, sample: SimSample) -> None:
        t = sample.state.sim_time_ns
        if t % CAMERA_PERIOD_NS:
            return
        self._file.write(_row(sample))
        if t - self._last_flush_ns >= NS_PER_S:
            self._file.flush()
            self._last_flush_ns = t

    def close(self, result: FlightResult) -> None:
        self._file.close()


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


class FlightStats:
    """Summary metrics: capture frames and distance, tracking errors, waypoints reached."""

    def __init__(self, waypoints_total: int) -> None:
        self.waypoints_total = waypoints_total
        self.reached: set[int] = set()
        self.capture_frames = 0
        self.capture_distance_m = 0.0
        # None until a settled segment has been measured (summary: null, not a false 0.0).
        self.max_cross_track_m: float | None = None
        self.max_alt_error_m: float | None = None
        self.capture_start_ns: int | None = None
        self.capture_end_ns: int | None = None
        self._last_capture_ne: tuple[float, float] | None = None
        self.mission_completed = False
        self.sim_time_ns = 0

    def add(self, sample: SimSample) -> None:
        """Account for one physics sample."""
        s = sample.state
        a = sample.autopilot
        self.sim_time_ns = s.sim_time_ns
        if a.reached_seq >= 0:
            self.reached.add(a.reached_seq)
        if a.mission_completed:
            self.mission_completed = True
        if a.tracking_settled:
            if not math.isnan(a.cross_track_m):
                self.max_cross_track_m = max(self.max_cross_track_m or 0.0, abs(a.cross_track_m))
            if not math.isnan(a.alt_error_m):
                self.max_alt_error_m = max(self.max_alt_error_m or 0.0, abs(a.alt_error_m))
        if s.sim_time_ns % CAMERA_PERIOD_NS:
            return
        if a.capturing:
            ne = (s.pos_ned_m[0], s.pos_ned_m[1])
            if self._last_capture_ne is not None:
                self.capture_distance_m += math.dist(ne, self._last_capture_ne)
            else:
                self.capture_start_ns = s.sim_time_ns
            self._last_capture_ne = ne
            self.capture_frames += 1
            self.capture_end_ns = s.sim_time_ns
        else:
            self._last_capture_ne = None

    def summary(self, wall_time_s: float) -> dict[str, Any]:
        """The content of ``summary.json``."""
        sim_s = self.sim_time_ns / NS_PER_S
        return {
            "mission_completed": self.mission_completed,
            "capture_frames": self.capture_frames,
            "capture_distance_m": round(self.capture_distance_m, 3),
            "capture_start_s": None
            if self.capture_start_ns is None
            else self.capture_start_ns / NS_PER_S,
            "capture_end_s": None
            if self.capture_end_ns is None
            else self.capture_end_ns / NS_PER_S,
            "max_cross_track_m": _rounded(self.max_cross_track_m),
            "max_alt_error_m": _rounded(self.max_alt_error_m),
            "sim_time_s": sim_s,
            "wall_time_s": round(wall_time_s, 3),
            "realtime_factor": round(sim_s / wall_time_s, 1) if wall_time_s > 0 else None,
            "waypoints_reached": len(self.reached),
            "waypoints_total": self.waypoints_total,
        }
