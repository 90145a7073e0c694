"""What changes in the ``urban`` map from one survey to the next (layout frame, no pixels).

- change over years: blocks are redeveloped at a steady rate per year (construction sites,
  then new homes, shops or parking lots), and other blocks or fields get a new street cut
  through them or a new parking lot on one side; so the changed share grows with the years
  between two dates, and what was built stays;
- moving things: parked cars are drawn anew for each survey (which stalls are taken, which
  car stands there);
- seasons: each field's crop rotates from year to year; deciduous trees stand bare in spring.
"""

from __future__ import annotations

import math

import numpy as np

from air_sitl.maps.procedural.canvas import DATES, Canvas, Color, DateLook, Point, rect, shade
from air_sitl.maps.procedural.noise import rng_for, unit_of
from air_sitl.maps.procedural.urban_blocks import (
    CAR_COLOURS,
    CROP_KINDS,
    Block,
    Building,
    box,
    parking_rows,
)

REBUILT_PER_YEAR = 0.014  # share of blocks redeveloped per year
# Share of the fields at the town's edge (next to a built block) built over per year: new
# subdivisions, as on the real suburbs' pairs (LEVIR-CD: a growing town's new streets and
# homes on former open land).
GROWTH_PER_YEAR = 0.04
CAR_OCCUPANCY = 0.72  # share of the car places taken during a survey
_SITE_GROUND = "dirt"
_SITE_ROOFS: tuple[Color, ...] = ((150, 156, 160), (120, 126, 130), (170, 172, 170))
_CARS: tuple[Color, ...] = (*CAR_COLOURS, (110, 110, 112))  # a survey's cars: one grey more
# Autumn broadleaves, each tree its own: still green, yellow, orange, brown (BGR).
AUTUMN_LEAVES: tuple[Color, ...] = ((40, 86, 58), (44, 156, 184), (36, 104, 180), (48, 82, 116))
BARE_BRANCHES: Color = (78, 88, 98)  # leafless crowns: grey-brown twigs (BGR)
CONIFER_INDEX = 2  # urban trees of colour index 2 are evergreen
NEW_PAVING_PER_YEAR = 0.02  # share of blocks (and fields) given a new street or lot a year
NEW_STREET_SHARE = 0.4  # of those, a new street cut through; the others a new parking lot
NEW_STREET_HALF_M = 4.0  # half width of a new street's asphalt
NEW_WALK_M = 2.0  # its sidewalks (verges through fields)
MARKING_M = 0.3  # width of a new street's lane markings


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


def developed_at(seed: int, kx: int, ky: int) -> int:
    """First date index at which field block (kx, ky), at the town's edge, has been built
    over (99: never); what is built by a date stays built at every later date."""
    u = unit_of(seed, 0xB4, kx, ky)
    for d in range(1, len(DATES)):
        if u < GROWTH_PER_YEAR * (year_of(d) - year_of(0)):
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


def autumn_crown(seed: int, c: Point) -> Color:
    """The colour a broadleaf crown centred at ``c`` (layout frame) has in the autumn survey."""
    u = unit_of(seed, 0xAC, round(c[0] * 10), round(c[1] * 10))
    return AUTUMN_LEAVES[int(u * len(AUTUMN_LEAVES))]


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


def paved_at(seed: int, kx: int, ky: int) -> int:
    """First date index at which block (kx, ky) has a new street or parking lot (99: never).

    One draw per block against a share growing with the years: what is paved by a date
    stays paved at every later date, and later dates have more of it."""
    u = unit_of(seed, 0xB2, kx, ky)
    for d in range(1, len(DATES)):
        if u < NEW_PAVING_PER_YEAR * (year_of(d) - year_of(0)):
            return d
    return 99


def new_paving(seed: int, kx: int, ky: int, block: Block) -> Block:
    """``block`` with its new street or parking lot: what stood there is cleared away.

    The street or lot is drawn from the block's own generator, never from the date, so it
    is the same at every survey from the one it first appears in."""
    rng = rng_for(seed, 0xB3, kx, ky)
    if rng.random() < NEW_STREET_SHARE:
        return _new_street(rng, block)
    return _new_lot(rng, block)


def has_new_street(seed: int, kx: int, ky: int) -> bool:
    """Whether block (kx, ky)'s new paving (if it gets any) is a street, not a lot."""
    return bool(rng_for(seed, 0xB3, kx, ky).random() < NEW_STREET_SHARE)


def _new_street(rng: np.random.Generator, block: Block) -> Block:
    """A street cut across the block's long side, from one street to the opposite one."""
    u0, v0, u1, v1 = block.bounds
    along_u = (u1 - u0) >= (v1 - v0)
    lo, hi = (u0, u1) if along_u else (v0, v1)
    at = lo + (hi - lo) * rng.uniform(0.35, 0.65)
    outer = NEW_STREET_HALF_M + NEW_WALK_M

    def band(a: float, b: float) -> tuple[float, float, float, float]:
        return (a, v0, b, v1) if along_u else (u0, a, u1, b)

    cleared = _cleared(block, band(at - outer, at + outer))
    edge = "verge" if is_fields(block) else "sidewalk"
    grounds = (
        *cleared.grounds,
        (tuple(box(*band(at - outer, at + outer))), edge),
        (tuple(box(*band(at - NEW_STREET_HALF_M, at + NEW_STREET_HALF_M))), "newroad"),
    )
    # Markings: a dashed centre line (6 m of 9, as on the old minor streets), stop lines.
    a0, a1 = (v0, v1) if along_u else (u0, u1)
    marks: list[tuple[tuple[Point, ...], float]] = []
    t = a0 + 2.0
    while t + 6.0 < a1 - 2.0:
        marks.append((_across(along_u, at, t, at, t + 6.0), MARKING_M))
        t += 9.0
    for end, side in ((a0 + 1.0, 1.0), (a1 - 1.0, -1.0)):
        near = at - side * NEW_STREET_HALF_M * 0.9
        marks.append((_across(along_u, at, end, near, end), 2 * MARKING_M))
    return Block(
        grounds=grounds,
        buildings=cleared.buildings,
        trees=cleared.trees,
        cars=cleared.cars,
        paint=(*cleared.paint, *marks),
        bounds=block.bounds,
    )


def _across(along_u: bool, a: float, t0: float, b: float, t1: float) -> tuple[Point, ...]:
    """A segment from (a, t0) to (b, t1) in (across, along) a new street: layout (u, v)."""
    return ((a, t0), (b, t1)) if along_u else ((t0, a), (t1, b))


def _new_lot(rng: np.random.Generator, block: Block) -> Block:
    """A paved parking lot along one long side of the block: rows of stalls, cars, trees."""
    u0, v0, u1, v1 = block.bounds
    b0, b1, c0, c1 = u0 + 2.5, u1 - 2.5, v0 + 2.5, v1 - 2.5
    along_u = (b1 - b0) >= (c1 - c0)
    short = (c1 - c0) if along_u else (b1 - b0)
    depth = min(short, max(14.0, short * rng.uniform(0.4, 0.6)))
    near = rng.random() < 0.5
    if along_u:
        lot = (b0, c0, b1, c0 + depth) if near else (b0, c1 - depth, b1, c1)
    else:
        lot = (b0, c0, b0 + depth, c1) if near else (b1 - depth, c0, b1, c1)
    cleared = _cleared(block, (lot[0] - 0.5, lot[1] - 0.5, lot[2] + 0.5, lot[3] + 0.5))
    cars = list(cleared.cars)
    paint = list(cleared.paint)
    trees = list(cleared.trees)
    parking_rows(rng, *lot, cars, paint, trees)
    return Block(
        grounds=(*cleared.grounds, (tuple(box(*lot)), "newlot")),
        buildings=cleared.buildings,
        trees=tuple(trees),
        cars=tuple(cars),
        paint=tuple(paint),
        bounds=block.bounds,
    )


def _cleared(block: Block, area: tuple[float, float, float, float]) -> Block:
    """``block`` without the buildings, trees, cars and paint reaching into ``area`` (u0,
    v0, u1, v1): cleared for new paving (its grounds stay, the paving is drawn over them)."""
    a0, b0, a1, b1 = area

    def clear(pts: tuple[Point, ...], margin: float = 0.0) -> bool:
        us = [p[0] for p in pts]
        vs = [p[1] for p in pts]
        return (
            max(us) < a0 - margin
            or min(us) > a1 + margin
            or max(vs) < b0 - margin
            or min(vs) > b1 + margin
        )

    return Block(
        grounds=block.grounds,
        buildings=tuple(b for b in block.buildings if clear(b.corners)),
        # Crowns grow 12 % a survey: cleared with room for the widest they become.
        trees=tuple(t for t in block.trees if clear((t[0],), 1.3 * t[1])),
        cars=tuple(c for c in block.cars if clear(c[0])),
        paint=tuple(p for p in block.paint if clear(p[0])),
        bounds=block.bounds,
    )
