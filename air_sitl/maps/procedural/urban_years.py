"""What the years do to the ``urban`` map's objects, each along its own outline: lawns and
verges watered green or dried to straw, parking lots, driveways and street stretches
resurfaced in black asphalt or left to go pale, roofs re-roofed lighter or darker. The
share of objects changed since the reference survey grows with the years
(``yeargap.changed``); each survey draws a changed object's look anew. So the contrast of
a lawn against the street, of a roof against its yard, of a lot against its verge, flips
on some objects from one survey to another, as on real imagery of different years.
"""

from __future__ import annotations

import itertools
from dataclasses import replace

from air_sitl.maps.procedural.canvas import Color, DateLook, Point
from air_sitl.maps.procedural.urban_blocks import Building
from air_sitl.maps.procedural.yeargap import look

# Mean years between two changes of an object's look (calibrated on real pairs: see
# docs/map-dates.md, "What years do to the ground").
EVERY_YEARS = {
    "lawn": 2.0,  # watering, drought, re-seeding, paving over
    "verge": 2.0,
    "parking": 4.0,  # resurfaced or sealed black, or faded
    "driveway": 6.0,
    "sidewalk": 8.0,
    "street": 4.0,  # a stretch between two crossings
    "roof": 6.0,
}
_LAWN_LOOKS: tuple[Color, ...] = (  # BGR
    (118, 160, 180),  # straw: a dry summer
    (100, 140, 156),  # dry, patchy
    (40, 88, 54),  # lush, watered: dark green
    (62, 96, 100),  # worn, bare soil showing
)
_PAVING_LOOKS: tuple[Color, ...] = (
    (40, 40, 42),  # fresh asphalt, black
    (58, 58, 60),  # sealed
    (150, 152, 152),  # old asphalt, faded pale
    (186, 190, 190),  # concrete
)
_ROOF_LOOKS: tuple[Color, ...] = (
    (54, 56, 60),  # dark shingles
    (200, 202, 202),  # light, white membrane
    (150, 154, 158),  # grey metal
    (60, 84, 150),  # red-brown tiles
    (110, 140, 170),  # tan shingles
)
_LOOKS = {
    "lawn": _LAWN_LOOKS,
    "verge": _LAWN_LOOKS,
    "parking": _PAVING_LOOKS,
    "driveway": _PAVING_LOOKS,
    "sidewalk": _PAVING_LOOKS,
    "street": _PAVING_LOOKS,
    "roof": _ROOF_LOOKS,
}
_TAGS = {"lawn": 1, "verge": 2, "parking": 3, "driveway": 4, "street": 5, "roof": 6, "sidewalk": 7}


def object_look(seed: int, date: DateLook, kind: str, at: Point, col: Color) -> Color:
    """The colour of an object of ``kind`` (a ground kind, ``street`` or ``roof``) whose
    outline starts at ``at`` (layout frame) in this survey: ``col`` (its reference look)
    unless the years changed it."""
    looks = _LOOKS.get(kind)
    if looks is None:
        return col
    qx, qy = round(at[0] * 8.0), round(at[1] * 8.0)
    i = look(seed, date, EVERY_YEARS[kind], len(looks), _TAGS[kind], qx, qy)
    return col if i is None else looks[i]


def reroofed(seed: int, date: DateLook, b: Building) -> Building:
    """The building with this survey's roof (re-roofed since the reference survey, or not)."""
    roof = object_look(seed, date, "roof", b.corners[0], b.roof)
    return b if roof == b.roof else replace(b, roof=roof)


def street_stretches(
    seed: int, date: DateLook, axis: int, k: int, crossings: list[float]
) -> list[tuple[float, float, Color]]:
    """(start, end, colour) along street ``k`` of ``axis`` (layout metres) of the stretches
    between consecutive ``crossings`` resurfaced or faded since the reference survey."""
    out = []
    for a, b in itertools.pairwise(crossings):
        col = object_look(seed, date, "street", (1000.0 * axis + k, a), (0, 0, 0))
        if col != (0, 0, 0):
            out.append((a, b, col))
    return out
