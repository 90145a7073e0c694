"""What the years do to the ``forest`` map's stands and meadows, each along its own outline:
compartments thinned, their canopy opened or closed, drought-struck or flushed (the crowns
of a whole compartment brighter or darker), meadows mown, grazed, dried to straw or grown
lush. The share changed since the reference survey grows with the years (``yeargap``);
clear-cuts, regrowth, lakes and ponds are drawn by the forest itself.

Compartments are the forest's management units: straight-sided lots ``COMPARTMENT_M`` long
in rows each shifted by its own amount, as forest maps divide a managed forest.
"""

from __future__ import annotations

import numpy as np

from air_sitl.maps.procedural.canvas import Color, DateLook
from air_sitl.maps.procedural.noise import FloatImage, key_of, unit2
from air_sitl.maps.procedural.yeargap import changed_cells, changed_share, years_since_reference

COMPARTMENT_M = (180.0, 120.0)  # east, north
STAND_EVERY_YEARS = 8.0  # mean years between changes of a compartment's canopy
STAND_TONE = (0.72, 1.32)  # the canopy's brightness after a change: darker .. brighter
TREE_EVERY_YEARS = 2.0  # mean years between changes of a tree crown (health, flowering)
TREE_TONE = 1.2  # a changed crown's brightness: 1 +- this / 2
MEADOW_EVERY_YEARS = 2.5  # meadows: mown, grazed or dry one year, lush the next
# A changed meadow's look (BGR): straw, dry, freshly mown green, lush dark green.
MEADOW_LOOKS: tuple[Color, ...] = ((120, 168, 186), (96, 140, 150), (70, 140, 100), (44, 92, 58))


def _compartments(
    x0: int, y0: int, size: int, gsd_m: float, seed: int
) -> tuple[np.ndarray, np.ndarray]:
    """Lattice indices (column, row) of the compartment of each pixel."""
    e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    s = (y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    rows = np.floor(s / COMPARTMENT_M[1]).astype(np.int64)[:, None]
    shift = unit2(rows, rows * 0 + 3, key_of(seed, 0x7C0))
    cols = np.floor(e[None, :] / COMPARTMENT_M[0] + shift).astype(np.int64)
    return cols, np.broadcast_to(rows, cols.shape)


def stand_tone(seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """Brightness gain of the crowns of each pixel's compartment in this survey (1: as at the
    reference survey)."""
    if years_since_reference(date) <= 0.0:
        return np.ones((size, size), np.float32)
    cols, rows = _compartments(x0, y0, size, gsd_m, seed)
    moved = changed_cells(seed, date, STAND_EVERY_YEARS, cols, rows, 1)
    u = unit2(cols, rows, key_of(seed, 0x7C1, date.index))
    gain = STAND_TONE[0] + (STAND_TONE[1] - STAND_TONE[0]) * u
    out: FloatImage = np.where(moved, gain, 1.0).astype(np.float32)
    return out


def meadow_look(
    seed: int,
    date: DateLook,
    x0: int,
    y0: int,
    size: int,
    gsd_m: float,
    colour: Color,
    texture: FloatImage,
) -> FloatImage:
    """BGR of the meadows (each compartment's meadows mown, dry or lush as a whole), with
    ``texture`` (relative, per pixel)."""
    base = np.broadcast_to(np.array(colour, np.float32), (size, size, 3))
    if years_since_reference(date) > 0.0:
        cols, rows = _compartments(x0, y0, size, gsd_m, seed)
        moved = changed_cells(seed, date, MEADOW_EVERY_YEARS, cols, rows, 2)
        i = (unit2(cols, rows, key_of(seed, 0x7C2, date.index)) * len(MEADOW_LOOKS)).astype(int)
        looks = np.array(MEADOW_LOOKS, np.float32)[i]
        base = np.where(moved[:, :, None], looks, base)
    out: FloatImage = base * texture[:, :, None]
    return out


def tree_tone(date: DateLook, tint: FloatImage) -> FloatImage:
    """Brightness gain of each tree's crown in this survey (1: as at the reference survey):
    a share of the trees, growing with the years, stressed, dying back or flushed. Trees are
    told apart by their tint (each crown its own, ``crowns``)."""
    share = changed_share(years_since_reference(date), TREE_EVERY_YEARS)
    if share <= 0.0:
        return np.ones_like(tint)
    which = (tint * 7919.0) % 1.0  # a second uniform draw per tree, from its tint
    now = (tint * 104729.0 + 0.618 * date.index) % 1.0
    out: FloatImage = np.where(which < share, 1.0 + TREE_TONE * (now - 0.5), 1.0)
    return out.astype(np.float32)
