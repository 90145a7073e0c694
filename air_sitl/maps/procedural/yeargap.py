"""What years do to the ground between two surveys, object by object: each world's parcels,
roofs, lots, lawns, pavements, meadows and water bodies change along their own outlines, a
share growing with the years since the reference survey (date 0), on which nothing changes.

Real imagery of different years (public change-detection pairs: LEVIR 0.5 m suburbs 5-14
years apart, DSIFN peri-urban farmland; ``benchmarks/bench_dates.py`` measures them) differs
less by new buildings than by the tone of what stayed: a lawn green one year and straw the
next, a lot or street resurfaced black or left to go pale, a roof re-roofed lighter or darker,
a field in another crop or tilled, a pond full or dry. At the matcher's scale (2 m pixels,
32 m windows), 19 % (suburbs) to 43 % (farmland) of the textured windows have gradients that
disagree in sign: those objects' contrast against their neighbours inverted.

- :func:`changed` / :func:`look`: whether an object (a world's key: its kind and place) has
  changed since the reference survey, and which of the new looks it has; nested (what
  changed by one date has changed by every later one: one draw, a share growing with the
  years, ``1 - exp(-years / every_years)``);
- :func:`changed_cells`: the same for an array of parcels (fields, cells);
- :func:`water_level` and :func:`ponds`: shorelines that move by tens of metres from survey
  to survey, and small ponds that fill in a wet year and dry out in another.
- :func:`renewed_noise`: a material's texture (grass tufts, asphalt patches, crop growth),
  each octave renewed with the years: on real pairs the fine texture is each year's own.

Everything is a function of seed, object and date (tiles agree).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import DATES, DateLook
from air_sitl.maps.procedural.noise import (
    FloatImage,
    fractal_noise,
    key_of,
    unit2,
    unit_of,
    value_noise,
)

WATER_LEVEL = 0.09  # largest threshold offset of a water body (noise units), by 7 years
WATER_CELL_M = 900.0  # water bodies of one region rise and fall together
POND_CELL_M = 70.0  # feature size of small ponds
POND_THRESHOLD = 3.2  # hollows where the pond noise exceeds this (about 3 % of open land)
POND_SWING = 0.5  # how far a year moves the pond threshold (ponds fill and dry)
NOISE_STD = 1.74  # standard deviation of ``value_noise`` (measured over 4096 x 4096 px)


def years_since_reference(date: DateLook) -> float:
    """Years between the reference survey (date 0) and this one (0 on date 0)."""
    return max(0.0, float(int(date.label[:4]) - int(DATES[0].label[:4])))


def changed_share(years: float, every_years: float) -> float:
    """Share of objects changed ``years`` after the reference survey, for objects that change
    once every ``every_years`` on average."""
    return 1.0 - math.exp(-years / every_years)


def changed(seed: int, date: DateLook, every_years: float, *key: int) -> bool:
    """Whether the object ``key`` changed between the reference survey and ``date``."""
    share = changed_share(years_since_reference(date), every_years)
    return share > 0.0 and unit_of(seed, 0x7B0, *key) < share


def look(seed: int, date: DateLook, every_years: float, looks: int, *key: int) -> int | None:
    """Which of ``looks`` new looks the object ``key`` has at ``date`` (``None``: unchanged,
    as at the reference survey). Each survey draws the look anew (a lawn dry one year and
    green the next), from the surveys on which the object has changed."""
    if not changed(seed, date, every_years, *key):
        return None
    return int(unit_of(seed, 0x7B1, *key, date.index) * looks)


def changed_cells(
    seed: int,
    date: DateLook,
    every_years: float,
    ix: npt.NDArray[np.int64],
    iy: npt.NDArray[np.int64],
    tag: int,
) -> npt.NDArray[np.bool_]:
    """:func:`changed` for arrays of parcels (lattice indices ``ix``, ``iy``)."""
    share = changed_share(years_since_reference(date), every_years)
    out: npt.NDArray[np.bool_] = unit2(ix, iy, key_of(seed, 0x7B2, tag)) < share
    return out


def water_level(seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """Offset (noise units, to add to a water body's threshold) of this survey's water: 0 on
    the reference date, up to +-``WATER_LEVEL`` by 7 years; positive where the water stands
    higher. Regions (``WATER_CELL_M``) rise and fall on their own."""
    years = years_since_reference(date)
    if years <= 0.0:
        return np.zeros((size, size), np.float32)
    amp = WATER_LEVEL * min(1.0, years / 7.0)
    k = key_of(seed, 0x7A3, date.index)
    level = value_noise(k, x0 + 0.5, y0 + 0.5, size, WATER_CELL_M / gsd_m)
    out: FloatImage = np.clip(level / np.float32(NOISE_STD), -1.0, 1.0) * np.float32(amp)
    return out


def ponds(
    seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float, fill: float = 0.0
) -> FloatImage:
    """0..1: small ponds standing on open land during this survey. The same hollows every
    year; how many hold water is the year's (wet years fill more, dry years leave them dry),
    departing from the reference survey's more the more years lie between, and the season's
    (``fill``: how much shallower a hollow may be and still hold water, in the hollows' noise
    units; a spring survey's high water). The reference survey (date 0) was flown in a dry
    summer: its hollows hold no water."""
    if years_since_reference(date) <= 0.0:
        return np.zeros((size, size), np.float32)
    k = key_of(seed, 0x7A4)
    hollow = value_noise(k, x0 + 0.5, y0 + 0.5, size, POND_CELL_M / gsd_m)
    swing = POND_SWING * min(1.0, years_since_reference(date) / 7.0)
    k_wet = key_of(seed, 0x7A5, date.index)
    wet = value_noise(k_wet, x0 + 0.5, y0 + 0.5, size, 4.0 * POND_CELL_M / gsd_m) / NOISE_STD
    thr = np.float32(POND_THRESHOLD - fill) - np.float32(swing) * np.clip(wet, -1.5, 1.5)
    out: FloatImage = np.clip((hollow - thr) * np.float32(12.0), 0.0, 1.0)
    return out


# Mean years over which a material's texture becomes the year's own (grass tufts, asphalt
# patches, dirt on roofs, crop growth), set on real pairs of different years in windows
# without edges and not labelled changed (NCC of the band-passed pair, docs/map-dates.md):
# the fine texture (1-6 m) keeps 0.10 of its pattern over LEVIR's 5-14 years (0.02 in
# DSIFN's fields), the coarse patches (3-12 m: wear, soil, lawn patches) 0.31 (0.03).
FINE_EVERY_YEARS = 2.0
COARSE_EVERY_YEARS = 4.0


def renewed_noise(
    key: int,
    seed: int,
    date: DateLook,
    x0: int,
    y0: int,
    size: int,
    cell_px: float,
    octaves: int,
    coarse_octaves: int = 0,
) -> FloatImage:
    """``fractal_noise(key, ...)``, a material's texture, as this survey sees it: in each
    octave, the share renewed since the reference survey is the year's own (the same
    variance); the first ``coarse_octaves`` renew over ``COARSE_EVERY_YEARS``, the finer
    ones over ``FINE_EVERY_YEARS``."""
    years = years_since_reference(date)
    if years <= 0.0:
        return fractal_noise(key, x0, y0, size, cell_px, octaves)
    new_key = key_of(seed, 0x7D0, key, date.index)
    total = np.zeros((size, size), dtype=np.float32)
    amp, norm, cell = 1.0, 0.0, cell_px
    for o in range(octaves):
        if cell < 0.75:  # as fractal_noise
            break
        w = changed_share(years, COARSE_EVERY_YEARS if o < coarse_octaves else FINE_EVERY_YEARS)
        fixed = value_noise(key + 7919 * o, x0, y0, size, cell)
        new = value_noise(new_key + 7919 * o, x0, y0, size, cell)
        total += np.float32(amp * math.sqrt(1.0 - w * w)) * fixed + np.float32(amp * w) * new
        norm += amp * amp
        amp *= 0.5
        cell /= 2.0
    out: FloatImage = total * np.float32(1.0 / math.sqrt(max(norm, 1e-9)))
    return out
