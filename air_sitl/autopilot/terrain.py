"""Terrain following: the altitude demand of MAV_FRAME_GLOBAL_TERRAIN_ALT items (``--dem``).

A terrain-relative item is flown at its height above the surface under the aircraft, sampled
at the position the autopilot flies on (the onboard estimate), as ArduPilot's terrain
following does (PX4 refuses these frames at upload; QGroundControl converts terrain heights
to AMSL at the waypoints for it, which flies straight into a ridge between two waypoints).
Rising ground ahead raises the demand early (ArduPilot's TERRAIN_LOOKAHD): each sample
ahead asks for its height minus what the aircraft can climb on its way there.
"""

from __future__ import annotations

import dataclasses
import math

from air_sitl.autopilot.tasks import NavOutput, Tick
from air_sitl.frames import WGS84_A_M
from air_sitl.mission.geometry import SurfaceFn
from air_sitl.state import GeoPoint

LOOKAHEAD_S = 20.0  # how far ahead rising ground is looked for, in seconds of flight
LOOKAHEAD_SAMPLES = 8
LOOKAHEAD_EVERY = 10  # guidance updates between two looks ahead (50 Hz guidance: 5 Hz)
CLIMB_SHARE = 0.6  # share of the maximum climb rate counted on to clear ground ahead
MIN_LOOKAHEAD_SPEED_M_S = 10.0


def ground_amsl(surface: SurfaceFn | None, home: GeoPoint, lat_deg: float, lon_deg: float) -> float:
    """The ground at a point, where a landing there touches down: the DEM's (``--dem``), else
    home's (PX4 without a terrain estimate lands on the home altitude)."""
    return home.alt_amsl_m if surface is None else surface(lat_deg, lon_deg)


class TerrainFollower:
    """Altitude demands above the surface ``surface(lat_deg, lon_deg)`` (AMSL metres)."""

    def __init__(self, surface: SurfaceFn) -> None:
        self.surface = surface
        self._updates = 0
        self._ahead_m = -math.inf  # what the ground ahead asks for (AMSL), from the last look

    def ground_m(self, t: Tick) -> float:
        """The height the aircraft keeps its height above: the surface under it, or higher
        where the ground ahead rises faster than the aircraft can climb."""
        s = t.state
        here = self.surface(s.lat_deg, s.lon_deg)
        if self._updates % LOOKAHEAD_EVERY == 0:
            self._ahead_m = self._look_ahead(t)
        self._updates += 1
        return max(here, self._ahead_m)

    def _look_ahead(self, t: Tick) -> float:
        s = t.state
        speed = max(t.gs, MIN_LOOKAHEAD_SPEED_M_S)
        climb_m_s = CLIMB_SHARE * t.p.climb_max_m_s
        step_m = speed * LOOKAHEAD_S / LOOKAHEAD_SAMPLES
        cn, ce = math.cos(t.course), math.sin(t.course)
        m_per_deg_lat = math.radians(1.0) * WGS84_A_M
        m_per_deg_lon = m_per_deg_lat * max(math.cos(math.radians(s.lat_deg)), 1e-6)
        needed = -math.inf
        for k in range(1, LOOKAHEAD_SAMPLES + 1):
            d = k * step_m
            lat = s.lat_deg + d * cn / m_per_deg_lat
            lon = s.lon_deg + d * ce / m_per_deg_lon
            needed = max(needed, self.surface(lat, lon) - climb_m_s * d / speed)
        return needed

    def follow(self, out: NavOutput, t: Tick, height_m: float) -> NavOutput:
        """``out`` with its altitude demand ``height_m`` above the ground (:meth:`ground_m`)."""
        demand = self.ground_m(t) + height_m
        error = out.alt_error_m if math.isnan(out.alt_error_m) else t.alt - demand
        target = dataclasses.replace(out.target, altitude_amsl_m=demand)
        return dataclasses.replace(out, target=target, alt_error_m=error)
