"""Geofence geometry from MAVLink fence items: inclusion/exclusion circles and polygons.

Pure maths on a local flat-earth projection around the first vertex (fences are a few km).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from air_sitl.mission.items import MavCmd, MissionItem

_EARTH_RADIUS_M = 6_371_000.0

XY = tuple[float, float]


@dataclass(frozen=True, slots=True)
class Zone:
    """One fence zone: a circle (``radius_m`` > 0, one point) or a polygon (vertices)."""

    inclusion: bool
    points_deg: tuple[tuple[float, float], ...]  # (lat, lon)
    radius_m: float = 0.0


def _local(lat0: float, lon0: float, lat: float, lon: float) -> XY:
    x = math.radians(lon - lon0) * _EARTH_RADIUS_M * math.cos(math.radians(lat0))
    y = math.radians(lat - lat0) * _EARTH_RADIUS_M
    return x, y


def _inside_polygon(p: XY, poly: Sequence[XY]) -> bool:
    x, y = p
    inside = False
    n = len(poly)
    for i in range(n):
        x1, y1 = poly[i]
        x2, y2 = poly[(i + 1) % n]
        if (y1 > y) != (y2 > y) and x < (x2 - x1) * (y - y1) / (y2 - y1) + x1:
            inside = not inside
    return inside


def zones_of(items: Sequence[MissionItem]) -> tuple[Zone, ...]:
    """The zones of a validated fence list (polygons are runs of ``param1`` vertices)."""
    zones: list[Zone] = []
    i = 0
    while i < len(items):
        item = items[i]
        if item.command in (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION):
            inclusion = item.command == MavCmd.NAV_FENCE_CIRCLE_INCLUSION
            zones.append(Zone(inclusion, ((item.lat_deg, item.lon_deg),), item.param1))
            i += 1
        elif item.command in (
            MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
        ):
            count = max(int(item.param1), 1)
            run = items[i : i + count]
            inclusion = item.command == MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION
            zones.append(Zone(inclusion, tuple((v.lat_deg, v.lon_deg) for v in run)))
            i += count
        else:
            i += 1  # return point: not a zone
    return tuple(zones)


def inside(zone: Zone, lat_deg: float, lon_deg: float) -> bool:
    """True when the point lies in the zone."""
    lat0, lon0 = zone.points_deg[0]
    p = _local(lat0, lon0, lat_deg, lon_deg)
    if zone.radius_m > 0.0:
        return math.hypot(*p) <= zone.radius_m
    poly = [_local(lat0, lon0, la, lo) for la, lo in zone.points_deg]
    return len(poly) >= 3 and _inside_polygon(p, poly)


def breach(zones: Sequence[Zone], lat_deg: float, lon_deg: float) -> str | None:
    """Why the point breaks the fence (outside every inclusion, or inside an exclusion)."""
    inclusions = [z for z in zones if z.inclusion]
    if inclusions and not any(inside(z, lat_deg, lon_deg) for z in inclusions):
        return "outside the inclusion fence"
    for z in zones:
        if not z.inclusion and inside(z, lat_deg, lon_deg):
            return "inside an exclusion zone"
    return None
