"""How many camera frames a plan will capture, and from when: what ``dataset`` forecasts
(disk, progress totals) before anything flies.

The plan's legs are walked in order at its speed (the cruise speed, DO_CHANGE_SPEED after it):
straight lines between positioned items, the turns of LOITER_TURNS, the seconds of
LOITER_TIME. The capture window is the sequencer's (IMAGE_START .. IMAGE_STOP, else from the
first item after take-off to the end); ``--max-sim-time`` cuts it. Still air, no turn
radius: measured on AIR's UC-200 the window starts at 202 s (flown: 204 s) and holds 3,421
frames (flown: 3,436).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from air_sitl.mission.geometry import first_flown_item, item_point, loiter_geometry
from air_sitl.mission.items import MavCmd, Mission
from air_sitl.state import GeoPoint

CAMERA_RATE_HZ = 50.0
DEFAULT_SPEED_M_S = 15.0  # PX4's FW_AIRSPD_TRIM, when the plan names none
DEFAULT_LOITER_RADIUS_M = 80.0  # PX4's NAV_LOITER_RAD


@dataclass(frozen=True, slots=True, kw_only=True)
class CaptureForecast:
    """When capture starts (simulated seconds) and how many frames it will take."""

    start_s: float
    frames: int


def capture_forecast(
    mission: Mission,
    home: GeoPoint,
    *,
    air_start: bool = False,
    max_sim_time_s: float = math.inf,
    rate_hz: float = CAMERA_RATE_HZ,
) -> CaptureForecast:
    """The capture of ``mission`` flown from ``home`` (see the module docstring)."""
    items = mission.items
    explicit = any(
        i.command in (MavCmd.IMAGE_START_CAPTURE, MavCmd.IMAGE_STOP_CAPTURE) for i in items
    )
    first = first_flown_item(mission)
    speed = mission.cruise_speed_m_s
    if not (math.isfinite(speed) and speed > 0.0):
        speed = DEFAULT_SPEED_M_S
    t = 0.0
    here: tuple[float, float] = (0.0, 0.0)
    begin = max(first, 0) if air_start else 0
    if air_start and first >= 0:
        n, e, _ = item_point(items[first], home)
        here = (n, e)
    capturing = False
    start_s: float | None = None
    captured_s = 0.0
    for index in range(begin, len(items)):
        item = items[index]
        if item.command == MavCmd.DO_CHANGE_SPEED and item.param2 > 0.0:
            speed = item.param2
            continue
        if item.command == MavCmd.IMAGE_START_CAPTURE:
            capturing = True
            start_s = t if start_s is None else start_s
            continue
        if item.command == MavCmd.IMAGE_STOP_CAPTURE:
            capturing = False
            continue
        if item.command == MavCmd.NAV_RETURN_TO_LAUNCH:
            leg_s = math.hypot(*here) / speed
            here = (0.0, 0.0)
        else:
            n, e, _ = item_point(item, home)
            if math.isnan(n):
                continue
            distance_m = math.hypot(n - here[0], e - here[1])
            here = (n, e)
            if item.command == MavCmd.NAV_LOITER_TURNS:
                radius, _ = loiter_geometry(item, DEFAULT_LOITER_RADIUS_M)
                distance_m = abs(distance_m - radius)  # to the circle, then its turns
                distance_m += max(item.param1, 0.0) * 2.0 * math.pi * radius
            leg_s = distance_m / speed
            if item.command == MavCmd.NAV_LOITER_TIME:
                leg_s += max(item.param1, 0.0)
        if index == begin and air_start:
            leg_s = 0.0  # the air start begins there
        t += leg_s
        if capturing:
            captured_s += leg_s
        if not explicit and index == first:  # AIR's rule: from reaching the start point
            capturing, start_s = True, t
    start = t if start_s is None else start_s
    window_s = min(captured_s, max(0.0, max_sim_time_s - start))
    return CaptureForecast(start_s=start, frames=round(window_s * rate_hz))
