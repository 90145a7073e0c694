"""The flight core's own records: ``trajectory.csv`` (truth at 50 Hz) and the summary metrics.

Both are fed from the simulation thread. ``FlightStats`` is not a sink: the runner owns it and
hands its summary to every sink in :class:`~air_sitl.sinks.FlightResult`.
"""

from __future__ import annotations

import contextlib
import math
import os
from pathlib import Path
from typing import Any

from air_sitl.clock import CAMERA_PERIOD_NS, NS_PER_S
from air_sitl.errors import DatasetError
from air_sitl.files import write_all, write_error
from air_sitl.nav.columns import NAV_COLUMNS, nav_fields
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import AutopilotStatus, BatteryState, FlightMode, SimSample, VehicleState

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


# One row of TRAJECTORY_COLUMNS: ``%`` formats each value as the format spec of the same
# letters in an f-string would (bytes checked by tests/core/test_flight_fast_paths.py), in
# one call (a 50 Hz path: a quarter cheaper than the f-string's 21 fields).
_ROW_FORMAT = (
    "%d,%.9f,%.9f,%.4f,"  # time, lat, lon, alt
    "%.4f,%.4f,%.4f,%.8f,%.8f,%.8f,%.8f,"  # north, east, down, quaternion
    "%.4f,%.4f,%.4f,%.6f,%.6f,%.6f,%.4f,"  # velocity, rates, airspeed
    "%s,%d,%d\n"  # mode, mission_seq, capturing
)


def _row(sample: SimSample) -> str:
    s = sample.state
    a = sample.autopilot
    return _ROW_FORMAT % (
        s.sim_time_ns, s.lat_deg, s.lon_deg, s.alt_amsl_m, *s.pos_ned_m,
        *s.q_body_to_ned_wxyz, *s.vel_ned_m_s, *s.rate_frd_rad_s, s.airspeed_m_s,
        a.mode._value_, a.current_seq, a.capturing,  # _value_: .value without enum's property
    )  # fmt: skip


class TrajectoryWriter(NullSink):
    """Writes truth at 50 Hz over the whole flight to ``trajectory.csv``.

    Rows are written whole, once a simulated second, with ``os.write``; the bytes known on
    disk are counted. A write that fails (a full disk, an I/O error) cuts the file back to its
    last whole row and stops the flight with one line (DatasetError): the CSV stays readable
    to its last row, as the camera archive's files do.
    """

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_APPEND, 0o644)
        except OSError as err:
            msg = f"{path}: cannot write the trajectory: {err.strerror}"
            raise DatasetError(msg) from None
        self._size = 0  # bytes of whole rows on disk
        self._pending: list[str] = [",".join(self.columns()) + "\n"]
        self._last_flush_ns = 0
        self.error: DatasetError | None = None
        self._write_pending()

    def columns(self) -> tuple[str, ...]:
        """The header of the file."""
        return TRAJECTORY_COLUMNS

    def row(self, sample: SimSample) -> str:
        """One line of the file."""
        return _row(sample)

    def on_sample(self, sample: SimSample) -> None:
        t = sample.state.sim_time_ns
        if t % CAMERA_PERIOD_NS or self.error is not None:
            return
        self.add_row(t, self.row(sample))

    def add_row(self, t: int, row: str) -> None:
        """Append the row of the 50 Hz sample at ``t`` (written once a simulated second);
        :meth:`on_sample` formats it, files of one flight may share it."""
        if self.error is not None:
            return
        self._pending.append(row)
        if t - self._last_flush_ns >= NS_PER_S:
            self._write_pending()
            self._last_flush_ns = t

    def _write_pending(self) -> None:
        if not self._pending:
            return
        data = "".join(self._pending).encode("ascii")
        self._pending.clear()
        try:
            write_all(self._fd, data)
        except OSError as err:
            with contextlib.suppress(OSError):
                os.ftruncate(self._fd, self._size)  # back to the last whole row
            self.error = write_error(self.path, err)
            raise self.error from None
        self._size += len(data)

    def close(self, result: FlightResult) -> None:
        """Write what is left and close (a failure is kept in :attr:`error`: the runner closes
        the other sinks too; :meth:`raise_if_failed` reports it)."""
        if self._fd < 0:
            return
        try:
            if self.error is None:
                self._write_pending()
        except DatasetError:
            pass
        finally:
            os.close(self._fd)
            self._fd = -1

    def raise_if_failed(self) -> None:
        """The write error of the file, if any (one line)."""
        if self.error is not None:
            raise self.error


def _rounded(value: float | None) -> float | None:
    return None if value is None else round(value, 3)


# Ground contact: what separates a landing from a crash (a fixed wing on its wheels).
AIRBORNE_AGL_M = 5.0  # contact counts once the aircraft has been this high
CONTACT_AGL_M = 0.3  # wheels on the ground, or this close to it
MAX_TOUCHDOWN_SINK_M_S = 3.0  # a harder touchdown breaks the aircraft
MAX_TOUCHDOWN_ROLL_RAD = math.radians(30.0)  # a wing tip touches beyond this
MIN_TOUCHDOWN_PITCH_RAD = math.radians(-10.0)  # nose first below this


OBJECT_ABOVE_GROUND_M = 1.0  # a surface this far above the terrain is a roof or the canopy


def _contact_with(s: VehicleState) -> str:
    """What the aircraft touched: the ground, or (``--dem``) an object standing on it."""
    if s.surface_amsl_m is None or s.ground_amsl_m is None:
        return "ground contact"
    above = s.surface_amsl_m - s.ground_amsl_m
    if above <= OBJECT_ABOVE_GROUND_M or s.on_ground:
        return "ground contact"
    return f"contact with a roof or the canopy {above:.1f} m above the ground"


def _surface_fields(s: VehicleState) -> dict[str, float]:
    """Where on the surface a crash happened (``--dem``); nothing on the flat ground."""
    if s.surface_amsl_m is None:
        return {}
    fields = {"alt_amsl_m": round(s.alt_amsl_m, 2), "surface_amsl_m": round(s.surface_amsl_m, 2)}
    if s.ground_amsl_m is not None:
        fields["ground_amsl_m"] = round(s.ground_amsl_m, 2)
    return fields


class FlightStats:
    """Summary metrics: capture frames and distance, tracking errors, waypoints reached, and
    how the flight met the ground (``crashed`` where and why, or ``landed``).

    ``landing_items``: mission indices of NAV_LAND items; ground contact is a landing only
    while one is current or in LAND mode, within the sink-rate and attitude limits above.
    With a surface model (``--dem``) contact is with the surface under the aircraft: the
    terrain, a roof or the canopy.
    """

    def __init__(
        self, waypoints_total: int, *, landing_items: frozenset[int] = frozenset()
    ) -> None:
        self.waypoints_total = waypoints_total
        self.landing_items = landing_items
        self.crashed: dict[str, Any] | None = None
        self.touched_down = False  # a proper touchdown in a landing
        self._airborne = False
        self._in_contact = False
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
        self.battery: BatteryState | None = None
        self.min_battery_v: float | None = None
        self._tracked: AutopilotStatus | None = None  # the status whose errors are counted

    def add(self, sample: SimSample) -> None:
        """Account for one physics sample (a 200 Hz path: the common case written out)."""
        s = sample.state
        a = sample.autopilot
        t = self.sim_time_ns = s.sim_time_ns
        b = sample.battery
        if b is not None:
            self.battery = b
            v = b.voltage_v
            low = self.min_battery_v
            self.min_battery_v = v if low is None or v < low else low  # as min(low, v)
        if a.reached_seq >= 0:
            self.reached.add(a.reached_seq)
        if self.crashed is None:
            surface = s.surface_amsl_m  # s.surface_agl_m written out (a 200 Hz path)
            agl = s.alt_agl_m if surface is None else s.alt_amsl_m - surface
            if s.on_ground or agl < CONTACT_AGL_M:
                self._ground_contact(sample)
            else:  # in the air, clear of the surface: nothing to judge
                if agl > AIRBORNE_AGL_M:
                    self._airborne = True
                    self.touched_down = False
                self._in_contact = False
            if a.mission_completed and self.crashed is None:
                self.mission_completed = True
        if a.tracking_settled and a is not self._tracked:
            # Guidance's errors change at 50 Hz: a status seen already adds nothing.
            self._tracked = a
            if not math.isnan(a.cross_track_m):
                self.max_cross_track_m = max(self.max_cross_track_m or 0.0, abs(a.cross_track_m))
            if not math.isnan(a.alt_error_m):
                self.max_alt_error_m = max(self.max_alt_error_m or 0.0, abs(a.alt_error_m))
        if t % CAMERA_PERIOD_NS:
            return
        if a.capturing:
            ne = (s.pos_ned_m[0], s.pos_ned_m[1])
            if self._last_capture_ne is not None:
                self.capture_distance_m += math.dist(ne, self._last_capture_ne)
            else:
                self.capture_start_ns = t
            self._last_capture_ne = ne
            self.capture_frames += 1
            self.capture_end_ns = t
        else:
            self._last_capture_ne = None

    def _ground_contact(self, sample: SimSample) -> None:
        """Judge a sample in contact with the ground (on it, or under CONTACT_AGL_M above its
        surface; :meth:`add` tells): the first contact after being airborne is a landing, or
        a crash."""
        s = sample.state
        a = sample.autopilot
        if self._in_contact or not self._airborne:
            self._in_contact = True
            return
        self._in_contact = True
        landing = a.mode is FlightMode.LAND or a.current_seq in self.landing_items
        sink = s.vel_ned_m_s[2]
        if not landing:
            where = f"mode {a.mode.value}, mission item {a.current_seq}"
            reason = f"{_contact_with(s)} outside a landing ({where}), sink {sink:.1f} m/s"
        elif sink > MAX_TOUCHDOWN_SINK_M_S:
            reason = f"hard landing: sink {sink:.1f} m/s (limit {MAX_TOUCHDOWN_SINK_M_S:g} m/s)"
        elif abs(s.roll_rad) > MAX_TOUCHDOWN_ROLL_RAD or s.pitch_rad < MIN_TOUCHDOWN_PITCH_RAD:
            reason = (
                f"touchdown attitude: roll {math.degrees(s.roll_rad):.0f} deg, pitch "
                f"{math.degrees(s.pitch_rad):.0f} deg"
            )
        else:
            self.touched_down = True
            return
        self.crashed = {
            "sim_time_s": s.sim_time_ns / NS_PER_S,
            "lat_deg": round(s.lat_deg, 7),
            "lon_deg": round(s.lon_deg, 7),
            "reason": reason,
            **_surface_fields(s),
        }
        self.mission_completed = False

    @property
    def landed(self) -> bool:
        """A proper touchdown, and on the ground since."""
        return self.crashed is None and self.touched_down and self._in_contact

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
            "crashed": self.crashed,
            "landed": self.landed,
            "battery": self._battery_block(),
        }

    def _battery_block(self) -> dict[str, Any] | None:
        """The propulsion battery at the end of the flight (None when not modelled)."""
        b = self.battery
        if b is None:
            return None
        return {
            "consumed_mah": round(b.consumed_mah, 1),
            "consumed_wh": round(b.consumed_wh, 2),
            "remaining": round(b.remaining, 4),
            "voltage_v": round(b.voltage_v, 3),
            "min_voltage_v": _rounded(self.min_battery_v),
        }


class NavTrajectoryWriter(TrajectoryWriter):
    """TrajectoryWriter whose rows carry the onboard estimate too."""

    def columns(self) -> tuple[str, ...]:
        """Truth, then the onboard estimate."""
        return TRAJECTORY_COLUMNS + NAV_COLUMNS

    def row(self, sample: SimSample) -> str:
        """Truth, then the onboard estimate."""
        return f"{_row(sample)[:-1]},{nav_fields(sample.nav)}\n"
