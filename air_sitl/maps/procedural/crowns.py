"""Single tree crowns of the forest: one tree per 3.6 m cell of a world lattice, or none.

Each cell holds at most one tree, its centre jittered inside the cell, its species, height and
crown radius drawn from hashes of the cell and from stand fields sampled at the cell (so a
tree is the same at every zoom level and date). A pixel shows the highest crown covering it:
conifers as cones (narrow, dark, a sharp sunlit side), broadleaves as domes (wide, bright,
rounded). The result is the canopy surface in metres plus what the texture needs to shade it.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.noise import FloatImage, unit2, value_noise

CELL_M = 3.6
_JITTER = (0.15, 0.7)  # tree centre at (0.15 + 0.7 u) of its cell: never nearer a 2-away cell
GROWTH_PER_YEAR = 0.012  # trees grow taller (and their crowns wider) year by year
TURNOVER_PER_YEAR = 0.015  # share of the trees dying or felled (and of gaps filled) a year
MAX_RADIUS_M = 3.5  # < CELL_M * (1 + 0.15): every crown is found among the 3x3 cells around


class StandFields(NamedTuple):
    """Per-cell stand properties (n x n, first cell at lattice index (i0, j0))."""

    conifer: FloatImage  # probability that a tree is a conifer
    density: FloatImage  # probability that the cell holds a tree
    height_m: FloatImage  # stand top height


class Crowns(NamedTuple):
    """The crowns over a window of pixels."""

    height_m: FloatImage  # canopy surface above the ground (0 where no crown)
    lit: FloatImage  # -1 (crown side away from the sun) .. 1 (side facing it); 0 in gaps
    radial: FloatImage  # 0 at the crown's top .. 1 at its rim
    conifer: FloatImage  # 1 on a conifer crown, 0 on a broadleaf or in a gap
    tint: FloatImage  # per-tree colour variation in [0, 1)
    cover: FloatImage  # 1 on a crown, 0 in a gap


def stand_fields(key: int, c0x: float, c0y: float, n: int, step: float = 1.0) -> StandFields:
    """Stand fields (species patches, density, height) at n x n points ``step`` cells apart
    from cell coordinates (c0x, c0y) (cell i's centre is at i): the tree cells (step 1) or
    the pixels of a coarse level."""

    def field(salt: int, feature_m: float) -> FloatImage:
        return value_noise(key + salt, c0x / step, c0y / step, n, feature_m / CELL_M / step)

    species = field(1, 110.0) + 0.4 * field(2, 35.0)
    conifer = np.clip(0.5 + 1.6 * species, 0.0, 1.0).astype(np.float32)
    density = np.clip(0.82 + 0.3 * field(3, 70.0), 0.3, 1.0).astype(np.float32)
    tall = field(4, 240.0) + 0.5 * field(5, 60.0)
    height = np.clip(19.0 + 4.5 * tall, 8.0, 28.0)
    return StandFields(conifer, density, height.astype(np.float32))


def crowns(
    key: int,
    x0: int,
    y0: int,
    size: int,
    gsd_m: float,
    sun_es: tuple[float, float],
    keep: npt.NDArray[np.bool_] | None = None,
    years: int = 0,
) -> Crowns:
    """The crowns over pixels (x0.., y0..) of the lattice at ``gsd_m``.

    ``sun_es``: horizontal direction toward the sun as (east, south). ``keep`` (n x n cells
    from :func:`cell_window`) removes trees (clearings, water): False means no tree there.
    ``years`` since the first survey: trees grow taller and wider, some die or are felled
    (thinning, windthrow) and young trees fill some empty cells.
    """
    i0, j0, n = cell_window(x0, y0, size, gsd_m)
    stand = stand_fields(key, i0, j0, n)
    ii = np.arange(i0, i0 + n, dtype=np.int64)[None, :]
    jj = np.arange(j0, j0 + n, dtype=np.int64)[:, None]
    lo, span = _JITTER
    cx = ((ii + lo + span * unit2(ii, jj, key + 11)) * CELL_M).astype(np.float32)
    cy = ((jj + lo + span * unit2(ii, jj, key + 12)) * CELL_M).astype(np.float32)
    fate = unit2(ii, jj, key + 13)
    present = fate < stand.density
    if years > 0:  # turnover: a share of the trees gone, as many empty cells newly grown
        turnover = np.float32(TURNOVER_PER_YEAR * years)
        gone = fate < stand.density * turnover
        born = fate >= 1.0 - (1.0 - stand.density) * turnover
        present = (present & ~gone) | born
    if keep is not None:
        present &= keep
    conifer = unit2(ii, jj, key + 14) < stand.conifer
    top = stand.height_m * (0.82 + 0.26 * unit2(ii, jj, key + 15)).astype(np.float32)
    top = top * np.float32(1.0 + GROWTH_PER_YEAR * years)
    radius = np.where(conifer, 0.1 * top + 0.6, 0.13 * top + 0.6)
    radius = np.minimum(radius, MAX_RADIUS_M).astype(np.float32)
    depth = np.where(conifer, 0.4, 0.3).astype(np.float32) * top
    top = np.where(present, top, np.float32(-1e3)).astype(np.float32)
    tint = unit2(ii, jj, key + 16).astype(np.float32)
    flat = [a.ravel() for a in (cx, cy, radius, depth, top)]
    # Pixel centres in metres (east, south) and their cells.
    px_e = ((x0 + np.arange(size) + 0.5) * gsd_m).astype(np.float32)
    px_s = ((y0 + np.arange(size) + 0.5) * gsd_m).astype(np.float32)
    col_cell = np.floor(px_e / CELL_M).astype(np.int64) - i0
    row_cell = np.floor(px_s / CELL_M).astype(np.int64) - j0
    best_h = np.full((size, size), -1e3, dtype=np.float32)
    best_k = np.zeros((size, size), dtype=np.int64)
    best_s = np.ones((size, size), dtype=np.float32)
    for dj in (-1, 0, 1):
        for di in (-1, 0, 1):
            k = (row_cell[:, None] + dj) * n + (col_cell[None, :] + di)
            tx, ty, r, dep, h = (a.take(k) for a in flat)
            s2 = ((px_e[None, :] - tx) ** 2 + (px_s[:, None] - ty) ** 2) / (r * r)
            s = np.sqrt(np.minimum(s2, 1.0))
            cone = conifer.ravel().take(k)
            drop = np.where(cone, s, 1.0 - np.sqrt(1.0 - s * s))
            hgt = np.where(s2 < 1.0, h - dep * drop, np.float32(-1e3))
            better = hgt > best_h
            best_h = np.where(better, hgt, best_h)
            best_k = np.where(better, k, best_k)
            best_s = np.where(better, s, best_s)
    cover = (best_h > 0.0).astype(np.float32)
    tx, ty, r = (a.take(best_k) for a in flat[:3])
    lit = ((px_e[None, :] - tx) * sun_es[0] + (px_s[:, None] - ty) * sun_es[1]) / r
    return Crowns(
        height_m=np.maximum(best_h, 0.0).astype(np.float32),
        lit=(lit * cover).astype(np.float32),
        radial=np.where(cover > 0, best_s, 1.0).astype(np.float32),
        conifer=(conifer.ravel().take(best_k) * cover).astype(np.float32),
        tint=tint.ravel().take(best_k) * cover,
        cover=cover,
    )


def cell_window(x0: int, y0: int, size: int, gsd_m: float) -> tuple[int, int, int]:
    """First cell indices (i0, j0) and count n of the square of cells that holds every tree
    whose crown reaches pixels (x0.., y0..) at ``gsd_m``."""
    i0 = math.floor(x0 * gsd_m / CELL_M) - 2
    j0 = math.floor(y0 * gsd_m / CELL_M) - 2
    i1 = math.floor((x0 + size) * gsd_m / CELL_M) + 2
    j1 = math.floor((y0 + size) * gsd_m / CELL_M) + 2
    return i0, j0, max(i1 - i0, j1 - j0) + 1
