"""Blocks of the ``urban`` map: what stands between four streets (layout frame, no pixels).

A block holds grounds, buildings, trees, cars and white paint, drawn by ``urban``; every
random choice comes from the block's own generator, never from the date.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from air_sitl.maps.procedural.canvas import Color, Point, rect

_ROOFS: tuple[Color, ...] = (
    (120, 122, 128),
    (72, 74, 78),
    (58, 80, 166),
    (60, 82, 112),
    (46, 52, 140),
    (168, 188, 202),
    (118, 104, 92),
    (80, 100, 72),
    (150, 150, 150),
    (52, 64, 118),
    (96, 72, 58),
    (40, 44, 52),
)
_FLAT_ROOFS: tuple[Color, ...] = (
    (202, 204, 200),
    (150, 152, 150),
    (176, 178, 170),
    (110, 112, 112),
)
CAR_COLOURS: tuple[Color, ...] = (  # parked cars (BGR)
    (235, 235, 235),
    (30, 30, 30),
    (160, 160, 160),
    (40, 40, 170),
    (150, 80, 30),
    (200, 200, 205),
    (60, 60, 60),
)


@dataclass(frozen=True, slots=True)
class Building:
    """A building footprint (layout frame) with height, roof look and life span in dates."""

    corners: tuple[Point, ...]
    height_m: float
    roof: Color
    gabled: bool
    ridge_along_x: bool
    born: int  # first date index where it exists
    gone: int  # first date index where it no longer exists
    hipped: bool = False  # a gabled roof with sloped ends too (four facets)


@dataclass(frozen=True, slots=True)
class Block:
    """Everything in one block, in the layout frame."""

    grounds: tuple[tuple[tuple[Point, ...], str], ...]  # polygon, kind
    buildings: tuple[Building, ...]
    trees: tuple[tuple[Point, float, int, int], ...]  # centre, radius, colour index, born
    cars: tuple[tuple[tuple[Point, ...], Color], ...]
    paint: tuple[tuple[tuple[Point, ...], float], ...]  # white lines, width
    bounds: tuple[float, float, float, float]  # u0, v0, u1, v1


def fill_block(
    rng: np.random.Generator,
    kind: float,
    u0: float,
    v0: float,
    u1: float,
    v1: float,
    fields: bool = False,
) -> Block:
    """The content of a block between its streets: homes, shops, a park or a parking lot;
    or, out of town (``fields``), farm fields.

    ``kind`` in [0, 1) picks which; ``rng`` is the block's own generator.
    """
    edge = "verge" if fields else "sidewalk"
    grounds: list[tuple[tuple[Point, ...], str]] = [(tuple(box(u0, v0, u1, v1)), edge)]
    b0, b1, c0, c1 = u0 + 2.5, u1 - 2.5, v0 + 2.5, v1 - 2.5
    buildings: list[Building] = []
    trees: list[tuple[Point, float, int, int]] = []
    cars: list[tuple[tuple[Point, ...], Color]] = []
    paint: list[tuple[tuple[Point, ...], float]] = []
    if fields:
        _fields(rng, b0, c0, b1, c1, grounds, trees)
    elif kind < 0.62:
        grounds.append((tuple(box(b0, c0, b1, c1)), "lawn"))
        _residential(rng, b0, c0, b1, c1, grounds, buildings, trees, cars)
    elif kind < 0.8:
        grounds.append((tuple(box(b0, c0, b1, c1)), "parking"))
        _commercial(rng, b0, c0, b1, c1, buildings, trees, cars, paint)
    elif kind < 0.93:
        grounds.append((tuple(box(b0, c0, b1, c1)), "lawn"))
        _park(rng, b0, c0, b1, c1, grounds, trees)
    else:
        grounds.append((tuple(box(b0, c0, b1, c1)), "parking"))
        parking_rows(rng, b0, c0, b1, c1, cars, paint, trees)
    return Block(
        grounds=tuple(grounds),
        buildings=tuple(buildings),
        trees=tuple(trees),
        cars=tuple(cars),
        paint=tuple(paint),
        bounds=(u0, v0, u1, v1),
    )


def ridge_band(a0: Point, a1: Point, b0: Point, b1: Point) -> list[Point]:
    """The quarter to three-quarter band across edges a0-a1 and b0-b1 (ridge: their middles)."""

    def at(p: Point, q: Point, t: float) -> Point:
        return (p[0] + (q[0] - p[0]) * t, p[1] + (q[1] - p[1]) * t)

    return [at(a0, a1, 0.25), at(b0, b1, 0.25), at(b0, b1, 0.75), at(a0, a1, 0.75)]


def grown(pts: tuple[Point, ...], m: float) -> list[Point]:
    """A polygon moved outward by ``m`` metres along the rays from its centre (inward if
    negative): the ground a building site takes, a roof inside its parapet."""
    cu = sum(p[0] for p in pts) / len(pts)
    cv_ = sum(p[1] for p in pts) / len(pts)
    out = []
    for u, v in pts:
        du, dv = u - cu, v - cv_
        n = math.hypot(du, dv) or 1.0
        out.append((u + du / n * m, v + dv / n * m))
    return out


def box(u0: float, v0: float, u1: float, v1: float) -> list[Point]:
    return [(u0, v0), (u1, v0), (u1, v1), (u0, v1)]


def _residential(rng, b0, c0, b1, c1, grounds, buildings, trees, cars) -> None:  # type: ignore[no-untyped-def]
    """Two rows of lots back to back along the longer side of the block."""
    along_u = (b1 - b0) >= (c1 - c0)
    length = (b1 - b0) if along_u else (c1 - c0)
    depth = (c1 - c0) if along_u else (b1 - b0)
    n_lots = max(1, int(length // rng.uniform(16.0, 24.0)))
    lot_w = length / n_lots
    rows = 2 if depth > 34 else 1
    lot_d = depth / rows
    for row in range(rows):
        for i in range(n_lots):
            a0 = i * lot_w
            # lot-local: x along the row, y from the street inward
            hw = rng.uniform(0.28, 0.4) * lot_w
            hd = rng.uniform(0.22, 0.34) * min(lot_d, 40.0)
            setback = rng.uniform(5.0, 9.0)
            cx = a0 + lot_w / 2 + rng.uniform(-0.08, 0.08) * lot_w
            cy = setback + hd
            height = rng.uniform(5.0, 9.5)
            roof = _ROOFS[int(rng.integers(len(_ROOFS)))]
            gabled = rng.random() < 0.75
            hipped = gabled and rng.random() < 0.35
            ridge = rng.random() < 0.6
            life = rng.random()
            born, gone = (
                (1, 3)
                if life < 0.07
                else (2, 3)
                if life < 0.14
                else (0, 2)
                if life < 0.19
                else (0, 3)
            )
            recolor = rng.random() < 0.12
            pool = rng.random() < 0.12
            n_trees = int(rng.integers(0, 4))
            tree_xy = [
                (rng.uniform(0.1, 0.9) * lot_w + a0, rng.uniform(0.55, 0.95) * lot_d)
                for _ in range(n_trees)
            ]
            tree_r = [rng.uniform(2.0, 4.5) for _ in range(n_trees)]
            tree_c = [int(rng.integers(3)) for _ in range(n_trees)]
            car = rng.random() < 0.5
            car_col = CAR_COLOURS[int(rng.integers(len(CAR_COLOURS)))]

            def to_block(x: float, y: float, row: int = row) -> Point:
                yy = y if row == 0 else depth - y
                return (b0 + x, c0 + yy) if along_u else (b0 + yy, c0 + x)

            def poly(x0: float, y0: float, x1: float, y1: float) -> tuple[Point, ...]:
                return tuple(to_block(x, y) for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1)))

            house = poly(cx - hw, cy - hd, cx + hw, cy + hd)
            # Driveway from the street to the house side.
            dx0 = cx + hw + 0.5 if cx + hw + 4.0 < a0 + lot_w else cx - hw - 3.8
            grounds.append((poly(dx0, 0.0, dx0 + 3.2, cy + hd * 0.6), "driveway"))
            if pool:
                grounds.append((poly(cx - 2.5, cy + hd + 3.0, cx + 2.5, cy + hd + 7.0), "pool"))
            if car:
                cars.append((poly(dx0 + 0.7, 1.0, dx0 + 2.5, 5.4), car_col))
            if recolor:
                # Re-roofed later: a second building record covering later dates.
                ridge_x = ridge ^ (not along_u)
                buildings.append(
                    Building(house, height, roof, gabled, ridge_x, born, min(gone, 2), hipped)
                )
                roof2 = _ROOFS[(_ROOFS.index(roof) + 3) % len(_ROOFS)]
                if gone > 2:
                    buildings.append(
                        Building(house, height, roof2, gabled, ridge_x, 2, gone, hipped)
                    )
            else:
                buildings.append(
                    Building(house, height, roof, gabled, ridge ^ (not along_u), born, gone, hipped)
                )
            for (tx, ty), tr, tc in zip(tree_xy, tree_r, tree_c, strict=True):
                p = to_block(tx, ty)
                trees.append((p, tr, tc, 0))


def _commercial(rng, b0, c0, b1, c1, buildings, trees, cars, paint) -> None:  # type: ignore[no-untyped-def]
    """One or two large flat-roofed buildings with rooftop units, cars and stall lines."""
    w, h = b1 - b0, c1 - c0
    n = 1 if rng.random() < 0.6 else 2
    for i in range(n):
        span = w / n
        bw = span * rng.uniform(0.45, 0.7)
        bh = h * rng.uniform(0.4, 0.65)
        cx = b0 + span * (i + 0.5)
        cy = c0 + h * rng.uniform(0.3, 0.7)
        roof = _FLAT_ROOFS[int(rng.integers(len(_FLAT_ROOFS)))]
        height = rng.uniform(8.0, 30.0)
        life = rng.random()
        born, gone = (1, 3) if life < 0.1 else (2, 3) if life < 0.18 else (0, 3)
        buildings.append(
            Building(
                tuple(rect(cx, cy, bw / 2, bh / 2, 1.0, 0.0)), height, roof, False, True, born, gone
            )
        )
        for _ in range(int(rng.integers(2, 7))):
            ux = cx + rng.uniform(-0.35, 0.35) * bw
            uy = cy + rng.uniform(-0.35, 0.35) * bh
            s = rng.uniform(1.0, 2.5)
            buildings.append(
                Building(
                    tuple(rect(ux, uy, s, s * 0.7, 1.0, 0.0)),
                    height + 1.5,
                    (190, 190, 192),
                    False,
                    True,
                    born,
                    gone,
                )
            )
    _stalls(rng, b0 + 2, c0 + 2, b1 - 2, c0 + 0.18 * h, cars, paint)
    _stalls(rng, b0 + 2, c1 - 0.18 * h, b1 - 2, c1 - 2, cars, paint)
    for _ in range(int(rng.integers(2, 8))):
        trees.append(
            (
                (rng.uniform(b0, b1), rng.choice([c0 + 1.0, c1 - 1.0])),
                rng.uniform(2.0, 3.5),
                int(rng.integers(3)),
                0,
            )
        )


def _stalls(rng, u0, v0, u1, v1, cars, paint) -> None:  # type: ignore[no-untyped-def]
    """A row of parking stalls 2.6 m wide, some occupied."""
    n = max(0, int((u1 - u0) // 2.6))
    occupied = rng.random(n) < 0.4
    colours = rng.integers(len(CAR_COLOURS), size=n)
    cm = (v0 + v1) / 2
    for i in range(n):
        u = u0 + 2.6 * i
        paint.append((((u, v0), (u, v1)), 0.15))
        if occupied[i]:
            corners = (
                (u + 0.45, cm - 2.2),
                (u + 2.15, cm - 2.2),
                (u + 2.15, cm + 2.2),
                (u + 0.45, cm + 2.2),
            )
            cars.append((corners, CAR_COLOURS[int(colours[i])]))


def _park(rng, b0, c0, b1, c1, grounds, trees) -> None:  # type: ignore[no-untyped-def]
    """Lawn, a path across, clusters of trees and sometimes a pond."""
    grounds.append((((b0, c0), (b0 + 2.4, c0), (b1, c1), (b1 - 2.4, c1)), "path"))
    grounds.append(
        (
            (
                (b0 + (b1 - b0) / 2 - 1.2, c0),
                (b0 + (b1 - b0) / 2 + 1.2, c0),
                (b0 + (b1 - b0) / 2 + 1.2, c1),
                (b0 + (b1 - b0) / 2 - 1.2, c1),
            ),
            "path",
        )
    )
    for _ in range(int(rng.integers(4, 9))):
        cu, cv_ = rng.uniform(b0, b1), rng.uniform(c0, c1)
        for _ in range(int(rng.integers(3, 12))):
            trees.append(
                (
                    (cu + rng.normal(0, 7), cv_ + rng.normal(0, 7)),
                    rng.uniform(2.5, 5.5),
                    int(rng.integers(3)),
                    int(rng.random() < 0.15),
                )
            )


def parking_rows(rng, b0, c0, b1, c1, cars, paint, trees) -> None:  # type: ignore[no-untyped-def]
    """Rows of stalls with aisles between (a parking lot's stalls, cars and edge trees)."""
    v = c0 + 1.0
    while v + 11.0 <= c1:
        _stalls(rng, b0 + 1.0, v, b1 - 1.0, v + 5.0, cars, paint)
        v += 12.0
    for _ in range(int(rng.integers(0, 5))):
        trees.append(
            ((rng.uniform(b0, b1), c1 - 1.0), rng.uniform(2.0, 3.0), int(rng.integers(3)), 0)
        )


CROP_KINDS = 6  # ground kinds "crop0" .. "crop5": their colour depends on the season


def _fields(rng, b0, c0, b1, c1, grounds, trees) -> None:  # type: ignore[no-untyped-def]
    """Farm fields: strips across the block, each its own crop; a hedgerow on some edges."""
    along_u = (b1 - b0) >= (c1 - c0)
    length = (b1 - b0) if along_u else (c1 - c0)
    n = int(rng.integers(1, 4))
    cuts = np.sort(rng.uniform(0.25, 0.75, size=n - 1)) * length
    edges = [0.0, *cuts.tolist(), length]
    for a, b in itertools.pairwise(edges):
        crop = f"crop{int(rng.integers(CROP_KINDS))}"
        lo, hi = a + 0.6, b - 0.6  # a thin balk between fields
        poly = box(b0 + lo, c0, b0 + hi, c1) if along_u else box(b0, c0 + lo, b1, c0 + hi)
        grounds.append((tuple(poly), crop))
    if rng.random() < 0.5:  # a hedgerow along one long side
        near = rng.random() < 0.5
        t, end = (b0, b1) if along_u else (c0, c1)
        t += rng.uniform(0.0, 4.0)
        side = (c0 + 1.5 if near else c1 - 1.5) if along_u else (b0 + 1.5 if near else b1 - 1.5)
        while t < end:
            p = (t, side) if along_u else (side, t)
            trees.append((p, rng.uniform(1.8, 3.5), int(rng.integers(3)), 0))
            t += rng.uniform(3.0, 9.0)
