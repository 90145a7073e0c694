"""What changes in the ``urban`` map from one survey to the next (layout frame, no pixels).

- change over years: blocks are redeveloped at a steady rate per year (construction sites,
  then new homes, shops or parking lots), so the changed share grows with the years between
  two dates;
- moving things: parked cars are drawn anew for each survey (which stalls are taken, which
  car stands there);
- seasons: each field's crop rotates from year to year; deciduous trees stand bare in spring.
"""

from __future__ import annotations

import math

import numpy as np

from air_sitl.maps.procedural.canvas import DATES, Canvas, Color, DateLook, Point, rect, shade
from air_sitl.maps.procedural.noise import rng_for, unit_of
from air_sitl.maps.procedural.urban_blocks import CAR_COLOURS, CROP_KINDS, Block, Building, box

REBUILT_PER_YEAR = 0.014  # share of blocks redeveloped per year
CAR_OCCUPANCY = 0.72  # share of the car places taken during a survey
_SITE_GROUND = "dirt"
_SITE_ROOFS: tuple[Color, ...] = ((150, 156, 160), (120, 126, 130), (170, 172, 170))
_CARS: tuple[Color, ...] = (*CAR_COLOURS, (110, 110, 112))  # a survey's cars: one grey more
BARE_BRANCHES: Color = (78, 88, 98)  # leafless crowns: grey-brown twigs (BGR)
CONIFER_INDEX = 2  # urban trees of colour index 2 are evergreen


def year_of(index: int) -> int:
    """Year of a date index (the label's year)."""
    return int(DATES[min(index, len(DATES) - 1)].label[:4])


def rebuilt_at(seed: int, kx: int, ky: int) -> int:
    """First date index at which block (kx, ky) has been redeveloped (99: never)."""
    u = unit_of(seed, 0xB1, kx, ky)
    for d in range(1, len(DATES)):
        if u < REBUILT_PER_YEAR * (year_of(d) - year_of(0)):
            return d
    return 99


def is_fields(block: Block) -> bool:
    """Whether a block is farm fields (fields rotate crops instead of being rebuilt)."""
    return any(kind.startswith("crop") for _poly, kind in block.grounds)


def construction_site(
    rng: np.random.Generator, u0: float, v0: float, u1: float, v1: float
) -> Block:
    """A block being built: bare earth, a half-built frame or two, site cabins and trucks."""
    b0, b1, c0, c1 = u0 + 2.5, u1 - 2.5, v0 + 2.5, v1 - 2.5
    grounds = ((tuple(box(u0, v0, u1, v1)), "sidewalk"), (tuple(box(b0, c0, b1, c1)), _SITE_GROUND))
    buildings: list[Building] = []
    for i in range(int(rng.integers(1, 3))):
        cx = b0 + (b1 - b0) * (0.3 + 0.4 * i) + rng.uniform(-5, 5)
        cy = (c0 + c1) / 2 + rng.uniform(-8, 8)
        hw, hh = rng.uniform(8, 16), rng.uniform(6, 12)
        roof = _SITE_ROOFS[int(rng.integers(len(_SITE_ROOFS)))]
        corners = tuple(rect(cx, cy, hw, hh, 1.0, 0.0))
        buildings.append(Building(corners, rng.uniform(3.0, 9.0), roof, False, True, 0, 99))
    cars: list[tuple[tuple[Point, ...], Color]] = []
    for _ in range(int(rng.integers(2, 6))):
        cx, cy = rng.uniform(b0 + 4, b1 - 4), rng.uniform(c0 + 4, c1 - 4)
        along = rng.random() < 0.5
        hw, hh = (4.0, 1.25) if along else (1.25, 4.0)
        col = ((40, 170, 220), (230, 230, 230), (60, 60, 60))[int(rng.integers(3))]
        cars.append((tuple(rect(cx, cy, hw, hh, 1.0, 0.0)), col))
    return Block(
        grounds=grounds,
        buildings=tuple(buildings),
        trees=(),
        cars=tuple(cars),
        paint=(),
        bounds=(u0, v0, u1, v1),
    )


def parked_car(seed: int, date: DateLook, poly: tuple[Point, ...]) -> Color | None:
    """The car standing on a car place during this survey (None: the place is empty)."""
    qx, qy = round(poly[0][0] * 8.0), round(poly[0][1] * 8.0)
    if unit_of(seed, 0xCA, date.index, qx, qy) >= CAR_OCCUPANCY:
        return None
    return _CARS[int(unit_of(seed, 0xCB, date.index, qx, qy) * len(_CARS))]


def crop_index(seed: int, date: DateLook, poly: tuple[Point, ...], kind: str) -> int:
    """The crop grown on a field in this survey's year (a rotation, one crop a year)."""
    qx, qy = round(poly[0][0]), round(poly[0][1])
    turn = int(unit_of(seed, 0xC0, qx, qy) * CROP_KINDS)
    return (int(kind[4:]) + turn * (year_of(date.index) - year_of(0))) % CROP_KINDS


def bare_crown(cv: Canvas, seed: int, c: Point, r: float) -> None:
    """A leafless crown seen from above: twigs over a thin veil, the ground showing through."""
    rng = rng_for(seed, 0xBA, round(c[0] * 10), round(c[1] * 10))
    cv.circle(c, r * 0.9, (70,), "shadow")  # the veil of twigs darkens the ground a little
    for _ in range(7):
        a = rng.uniform(0.0, 2.0 * math.pi)
        end = (c[0] + r * 0.95 * math.cos(a), c[1] + r * 0.95 * math.sin(a))
        mid = (c[0] + r * 0.55 * math.cos(a + 0.25), c[1] + r * 0.55 * math.sin(a + 0.25))
        cv.line([c, mid, end], BARE_BRANCHES, 0.3)
    cv.circle(c, max(0.3, 0.12 * r), shade(BARE_BRANCHES, 0.8))
