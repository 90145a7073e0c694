"""Where mission items are: pure functions of a :class:`~air_sitl.mission.items.MissionItem`
(or a :class:`~air_sitl.mission.items.Mission`) and home, shared by the executor and air starts;
and the mission raised or lowered by ``--altitude-offset``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

from air_sitl.errors import OptionError
from air_sitl.frames import geodetic2ned
from air_sitl.mission.items import (
    LOITER_COMMANDS,
    RELATIVE_FRAMES,
    TERRAIN_FRAMES,
    WAYPOINT_COMMANDS,
    MavCmd,
    Mission,
    MissionItem,
)
from air_sitl.state import GeoPoint

# DO_JUMP chains with no navigation item in between end the mission after this many steps.
MAX_DO_STEPS = 10_000
POSITIONED_COMMANDS = LOITER_COMMANDS | WAYPOINT_COMMANDS

Point = tuple[float, float, float]  # north m, east m, altitude AMSL m
# Height AMSL of the surface under a (lat_deg, lon_deg): the terrain model of --dem.
SurfaceFn = Callable[[float, float], float]


def item_altitude_amsl(
    item: MissionItem, home: GeoPoint, surface: SurfaceFn | None = None
) -> float:
    """Altitude of a positioned item above mean sea level: relative frames add home's, terrain
    frames the surface's at the item (at home for an item without a position). Terrain frames
    are flown only with a surface model (validation refuses them otherwise); without one, the
    ground is home's."""
    if item.frame in RELATIVE_FRAMES:
        return home.alt_amsl_m + item.alt_m
    if item.frame in TERRAIN_FRAMES:
        if surface is None or not has_position(item):
            return home.alt_amsl_m + item.alt_m
        return surface(item.lat_deg, item.lon_deg) + item.alt_m
    return item.alt_m


def has_position(item: MissionItem) -> bool:
    """The item names a place (finite latitude and longitude, not the (0, 0) "here")."""
    return not (item.lat_deg == 0.0 and item.lon_deg == 0.0) and (
        math.isfinite(item.lat_deg) and math.isfinite(item.lon_deg)
    )


def item_point(item: MissionItem, home: GeoPoint, surface: SurfaceFn | None = None) -> Point:
    """Position of an item in home's NED frame; NaN north/east when it has none (0, 0)."""
    alt = item_altitude_amsl(item, home, surface)
    if not has_position(item):
        return (math.nan, math.nan, alt)
    n, e, _ = geodetic2ned(
        item.lat_deg, item.lon_deg, alt, home.lat_deg, home.lon_deg, home.alt_amsl_m
    )
    return (n, e, alt)


def loiter_geometry(item: MissionItem, default_radius_m: float) -> tuple[float, int]:
    """(radius, direction) of a loiter item; radius param sign: positive = clockwise."""
    raw = item.param2 if item.command == MavCmd.NAV_LOITER_TO_ALT else item.param3
    if not math.isfinite(raw) or abs(raw) < 1.0:
        return default_radius_m, 1
    return abs(raw), (1 if raw > 0 else -1)


def first_flown_item(mission: Mission) -> int:
    """Index of the first positioned navigation item after take-off (-1 if none).

    This is the "start point" of AIR: where ``--air-start`` places the aircraft and where the
    default capture window begins.
    """
    items = mission.items
    start = 0
    for i, item in enumerate(items):
        if item.command == MavCmd.NAV_TAKEOFF:
            start = i + 1
            break
    for i in range(start, len(items)):
        if items[i].command in POSITIONED_COMMANDS:
            return i
    return -1


def next_nav_index(items: tuple[MissionItem, ...], seq: int, jump_counts: dict[int, int]) -> int:
    """Index of the navigation item reached from ``seq`` onward (DO_JUMPs followed, counting
    in ``jump_counts``, which is updated); -1 at the end of the mission."""
    steps = 0
    n = len(items)
    while 0 <= seq < n:
        item = items[seq]
        if item.is_nav:
            return seq
        if item.command == MavCmd.DO_JUMP:
            count = jump_counts.get(seq, 0)
            if count < item.param2:
                jump_counts[seq] = count + 1
                seq = int(item.param1)
            else:
                seq += 1
        else:
            seq += 1
        steps += 1
        if steps > MAX_DO_STEPS:
            return -1
    return -1


# Items whose altitude is a height to fly at; RTL and landing keep theirs.
_SHIFTED_COMMANDS = frozenset({MavCmd.NAV_TAKEOFF, *POSITIONED_COMMANDS})


def shift_altitudes(mission: Mission, offset_m: float, home: GeoPoint) -> Mission:
    """``mission`` with every altitude it flies at (take-off, waypoints, loiters, rally points)
    raised by ``offset_m``; the capture items and their window stay as they are.

    OptionError when a shifted altitude is not above home (terrain frames: above the ground).
    """
    if offset_m == 0.0:
        return mission

    def shifted(item: MissionItem, index: int, kind: str) -> MissionItem:
        alt_m = item.alt_m + offset_m
        base = "the ground" if item.frame in TERRAIN_FRAMES else "home"
        relative = item.frame in RELATIVE_FRAMES or item.frame in TERRAIN_FRAMES
        above_m = alt_m if relative else alt_m - home.alt_amsl_m
        if above_m <= 0.0:
            msg = (
                f"--altitude-offset {offset_m:g}: {mission.source}: {kind} {index}: altitude "
                f"{item.alt_m:g} m would be {above_m:g} m above {base} (must stay above it)"
            )
            raise OptionError(msg)
        return replace(item, alt_m=alt_m)

    items = tuple(
        shifted(item, i, "item") if item.command in _SHIFTED_COMMANDS else item
        for i, item in enumerate(mission.items)
    )
    rally = tuple(shifted(item, i, "rally point") for i, item in enumerate(mission.rally))
    return replace(mission, items=items, rally=rally)
