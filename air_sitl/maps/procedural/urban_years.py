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
import math
from dataclasses import replace

import cv2
import numpy as np

from air_sitl.maps.procedural.canvas import Canvas, Color, DateLook, Point
from air_sitl.maps.procedural.noise import FloatImage, fractal_noise, key_of
from air_sitl.maps.procedural.urban_blocks import Building
from air_sitl.maps.procedural.yeargap import changed_share, look, years_since_reference

# Mean years between two changes of an object's look (calibrated on real pairs: see
# docs/map-dates.md, "What years do to the ground").
EVERY_YEARS = {
    "lawn": 2.0,  # watering, drought, re-seeding, paving over
    "verge": 2.0,
    "parking": 4.0,  # resurfaced or sealed black, or faded
    "driveway": 25.0,
    "sidewalk": 30.0,
    "street": 12.0,  # a stretch between two crossings
    "roof": 20.0,
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


FIELD_TEXTURE = 0.07  # relative amplitude of a crop field's growth pattern (8 m and finer)
FIELD_EVERY_YEARS = 1.0  # a field is sown anew each year: its pattern renews within years


def field_texture(
    cv: Canvas,
    seed: int,
    date: DateLook,
    fields: list[list[Point]],
    texture: FloatImage,
    cell_px: float,
) -> None:
    """Give the crop fields (world polygons) of a survey after the reference one the year's
    own growth pattern in ``texture`` (in place): a field is sown anew every year, its
    patches of growth, soil and moisture are mostly the year's (a share ``1 - exp(-years /
    FIELD_EVERY_YEARS)``; real farmland pairs of different years share 0.02 of it,
    docs/map-dates.md)."""
    new = changed_share(years_since_reference(date), FIELD_EVERY_YEARS)
    if not fields or new <= 0.0:
        return
    mask = np.zeros((cv.size, cv.size), np.uint8)
    cv2.fillPoly(mask, [cv.px(f) for f in fields], (255,), cv2.LINE_AA, 4)
    inside = mask > 0
    if not inside.any():
        return
    k = key_of(seed, 0x7E0, date.index)
    own = fractal_noise(k, cv.x0, cv.y0, cv.size, cell_px, 3)
    w = mask[inside].astype(np.float32) * np.float32(1.0 / 255.0)
    kept = np.float32(math.sqrt(1.0 - new * new))
    mixed = texture[inside] * kept + np.float32(FIELD_TEXTURE * new) * own[inside]
    texture[inside] = texture[inside] * (1.0 - w) + mixed * w
