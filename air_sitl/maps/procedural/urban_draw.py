"""Drawing helpers of the ``urban`` map: roofs, shadow hulls, and where roofs and crowns
cover the shadows beneath them."""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np

from air_sitl.maps.procedural.canvas import Canvas, Point, shade
from air_sitl.maps.procedural.urban_blocks import Building, grown


def hull(pts: list[Point]) -> list[Point]:
    """The convex hull of world points (a footprint and its shadow's far end)."""
    a = np.asarray(pts, dtype=np.float32)
    h = cv2.convexHull(a)
    return [(float(p[0][0]), float(p[0][1])) for p in h]


def erase_shadow(cv: Canvas, world: list[Point], _scratch: np.ndarray) -> None:
    """No shadow and no vegetation under a roof."""
    cv2.fillPoly(cv.shadow, [cv.px(world)], (0,), cv2.LINE_8, 4)
    cv2.fillPoly(cv.veg, [cv.px(world)], (0,), cv2.LINE_8, 4)


def erase_circle(cv: Canvas, c: Point, r: float) -> None:
    """No shadow under a crown."""
    p = cv.px([c])[0]
    cv2.circle(
        cv.shadow, (int(p[0]), int(p[1])), max(1, round(r / cv.gsd_m * 16)), (0,), -1, cv2.LINE_8, 4
    )


def draw_roof(
    cv: Canvas,
    layout_to_world: Callable[[list[Point] | tuple[Point, ...]], list[Point]],
    b: Building,
    world: list[Point],
    sun_e: float,
    sun_n: float,
    lean: Point = (0.0, 0.0),
) -> None:
    """A gabled roof in two shaded halves with a ridge (hipped: its ends sloped too, four
    facets), or a flat roof with a parapet; ``lean`` moves it off its footprint (metres)."""

    def to_world(pts: list[Point] | tuple[Point, ...]) -> list[Point]:
        return [(e + lean[0], n + lean[1]) for e, n in layout_to_world(pts)]

    p = b.corners
    if b.gabled:
        # The ridge joins the middles of the two short ends (e0, e1).
        e0, e1 = ((p[0], p[3]), (p[1], p[2])) if b.ridge_along_x else ((p[0], p[1]), (p[3], p[2]))
        m0 = ((e0[0][0] + e0[1][0]) / 2, (e0[0][1] + e0[1][1]) / 2)
        m1 = ((e1[0][0] + e1[1][0]) / 2, (e1[0][1] + e1[1][1]) / 2)
        r0, r1 = m0, m1
        if b.hipped:  # the ridge ends half the short side in from each end
            length = math.dist(m0, m1) or 1.0
            t = min(0.45, 0.5 * math.dist(*e0) / length)
            r0 = (m0[0] + (m1[0] - m0[0]) * t, m0[1] + (m1[1] - m0[1]) * t)
            r1 = (m1[0] + (m0[0] - m1[0]) * t, m1[1] + (m0[1] - m1[1]) * t)
        facets = [[e0[0], r0, r1, e1[0]], [r0, e0[1], e1[1], r1]]
        if b.hipped:
            facets += [[e0[0], e0[1], r0], [e1[0], e1[1], r1]]
        cx = sum(q[0] for q in world) / 4
        cy = sum(q[1] for q in world) / 4
        for facet in facets:
            w = to_world(facet)
            ce = sum(q[0] for q in w) / len(w) - cx
            cn = sum(q[1] for q in w) / len(w) - cy
            n = math.hypot(ce, cn) or 1.0
            lit = (ce * sun_e + cn * sun_n) / n
            cv.poly(w, shade(b.roof, 1.0 + 0.22 * lit))
        cv.line(to_world([r0, r1]), shade(b.roof, 1.3), 0.35)
    else:
        cv.poly(world, shade(b.roof, 0.78))
        cv.poly(to_world(grown(b.corners, -0.7)), b.roof)
