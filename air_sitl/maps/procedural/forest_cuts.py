"""Clear-cuts of the ``forest`` map and the tracks built to them (world frame, metres).

Managed forests are clear-cut at about 1 % of their area a year (rotations of 60-100 years), in
cuts of one to a few hectares: a 300 m cell gets at most one cut of 1-3 ha (100-220 x
70-150 m), felled by 2012 in 15 % of the cells and by 2016 in 36 % (3 % and 7 % of the area):
bare soil the survey that catches it, young growth after. Felling needs a way in: every cut gets a
logging track from the nearest node of the forest's track network, built when the cut is
felled and kept afterwards. All of it is found from cell indices alone, so any tile is drawn
without its neighbours and the built-in surface opens the same ground the texture shows.
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import DATES, Canvas, Point, rect
from air_sitl.maps.procedural.noise import rng_for, unit_of

TRACK_CELL_M = 380.0  # one node of the track network per cell
CUT_CELL_M = 300.0  # at most one clear-cut per cell
CUT_AREA_PER_YEAR = 0.01  # share of the forest felled a year
CUT_SIZE_M = ((100.0, 220.0), (70.0, 150.0))  # a cut's sides (uniform)
CUT_JITTER_M = 40.0  # a cut's centre off its cell's centre (it may reach past the cell)
_CUT_SHARE = (sum(CUT_SIZE_M[0]) / 2.0) * (sum(CUT_SIZE_M[1]) / 2.0) / CUT_CELL_M**2


class ClearCut(NamedTuple):
    """A clear-cut: the date index it is felled at (9: never), its centre and corners (m)."""

    at: int
    centre: Point
    corners: tuple[Point, ...]


@functools.lru_cache(maxsize=65536)
def track_node(seed: int, i: int, j: int) -> Point:
    """The node of the track network in cell (i, j), jittered inside the cell."""
    rng = rng_for(seed, 61, i, j)
    return (
        (i + rng.uniform(0.2, 0.8)) * TRACK_CELL_M,
        (j + rng.uniform(0.2, 0.8)) * TRACK_CELL_M,
    )


@functools.lru_cache(maxsize=65536)
def clear_cut(seed: int, i: int, j: int) -> ClearCut:
    """The clear-cut of cell (i, j): when it is felled and its rectangle."""
    rng = rng_for(seed, 51, i, j)
    u = rng.random()
    years = [year - int(DATES[0].label[:4]) for year in (int(d.label[:4]) for d in DATES)]
    by = [y * CUT_AREA_PER_YEAR / _CUT_SHARE for y in years]
    at = 1 if u < by[1] else 2 if u < by[2] else 9
    w, h = rng.uniform(*CUT_SIZE_M[0]), rng.uniform(*CUT_SIZE_M[1])
    cx = (i + 0.5) * CUT_CELL_M + rng.uniform(-CUT_JITTER_M, CUT_JITTER_M)
    cy = (j + 0.5) * CUT_CELL_M + rng.uniform(-CUT_JITTER_M, CUT_JITTER_M)
    a = rng.uniform(0, math.pi)
    return ClearCut(at, (cx, cy), tuple(rect(cx, cy, w, h, math.cos(a), math.sin(a))))


def cut_mask(
    seed: int, x0: int, y0: int, size: int, gsd_m: float, d: int
) -> npt.NDArray[np.float32] | None:
    """Mask of cells clear-cut at or before date ``d``: 1 where cut at ``d``, about 0.6
    where cut at an earlier date (young growth again); None where nothing is cut."""
    if d == 0:
        return None
    e0, e1 = x0 * gsd_m, (x0 + size) * gsd_m
    n0, n1 = -(y0 + size) * gsd_m, -y0 * gsd_m
    mask = np.zeros((size, size), dtype=np.uint8)
    cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
    cv.shadow = mask
    # Cuts reach at most half a cell past their own.
    for i in range(math.floor(e0 / CUT_CELL_M) - 1, math.floor(e1 / CUT_CELL_M) + 2):
        for j in range(math.floor(n0 / CUT_CELL_M) - 1, math.floor(n1 / CUT_CELL_M) + 2):
            cut = clear_cut(seed, i, j)
            if cut.at > d:
                continue
            value = 255 if cut.at == d else 160  # 160: cut a survey ago, growing again
            cv.poly(cut.corners, (value,), "shadow")
    if not mask.any():
        return None
    return mask.astype(np.float32) * np.float32(1.0 / 255.0)


def logging_tracks(
    seed: int, e0: float, n0: float, e1: float, n1: float, d: int
) -> list[list[Point]]:
    """The tracks to the clear-cuts felled by date index ``d`` that may reach the box (e0,
    n0)-(e1, n1): each from the nearest node of the track network, bending gently, into
    its cut. None at date 0, more at every later date; a track once built stays."""
    if d == 0:
        return []
    reach = 2.0 * TRACK_CELL_M  # no track is longer than this
    out: list[list[Point]] = []
    for i in range(
        math.floor((e0 - reach) / CUT_CELL_M), math.floor((e1 + reach) / CUT_CELL_M) + 1
    ):
        for j in range(
            math.floor((n0 - reach) / CUT_CELL_M), math.floor((n1 + reach) / CUT_CELL_M) + 1
        ):
            cut = clear_cut(seed, i, j)
            if cut.at > d:
                continue
            cx, cy = cut.centre
            ti, tj = math.floor(cx / TRACK_CELL_M), math.floor(cy / TRACK_CELL_M)
            nodes = [track_node(seed, ti + a, tj + b) for a in (-1, 0, 1) for b in (-1, 0, 1)]
            node = min(nodes, key=lambda p: math.dist(p, cut.centre))
            if (
                max(node[0], cx) < e0 - 20.0
                or min(node[0], cx) > e1 + 20.0
                or max(node[1], cy) < n0 - 20.0
                or min(node[1], cy) > n1 + 20.0
            ):
                continue
            length = math.dist(node, cut.centre) or 1.0
            bend = (unit_of(seed, 64, i, j) - 0.5) * 0.3 * length
            de, dn = (cx - node[0]) / length, (cy - node[1]) / length
            out.append(
                [
                    (
                        node[0] + de * length * t - dn * bend * math.sin(math.pi * t),
                        node[1] + dn * length * t + de * bend * math.sin(math.pi * t),
                    )
                    for t in np.linspace(0.0, 1.0, 13).tolist()
                ]
            )
    return out
