"""What years do to the ground between two surveys, for any world: local contrast inversion
and water that rises, falls, appears and dries. The amount grows with the years since the
reference survey (date 0), and nothing changes on date 0 itself.

Calibrated on real image pairs of different years (public change-detection samples: 0.5 m
suburbs 5-14 years apart, peri-urban farmland; ``benchmarks/bench_dates.py`` measures both),
at the scale a map matcher sees them (2 m pixels, 32 m windows): where nothing is labelled
changed, 14 % (suburbs) to 42 % (farmland) of the windows have gradients that disagree in
sign on average (single-angle orientation agreement below 0) while their doubled-angle
agreement stays positive: a field, lawn, roof or lot brighter than its surroundings one year
and darker the next. Before this model the procedural dates had 1-3 %.

- :func:`tone_change`: in patches of ground (about ``PATCH_M`` across) whose cover or
  brightness changed since the reference survey, grey levels pass through a non-monotonic
  curve: levels within about 60 grey levels of each other may swap order (a lawn gone dry
  against the asphalt beside it, a re-roofed house against its yard, a fallow field against
  a green one), while dark shadows and bright roofs keep theirs. Pointwise, so fine texture
  and object outlines stay where they are; only the sign of some of their edges flips.
- :func:`water_level` and :func:`ponds`: a threshold offset that moves shorelines by tens
  of metres from survey to survey, and small ponds that fill in a wet year and dry out in
  another (for a world's lakes, prairie ponds and wetlands).

Everything is a function of absolute lattice coordinates, seed and date (tiles agree).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import DATES, DateLook
from air_sitl.maps.procedural.noise import FloatImage, key_of, unit2, value_noise

Bgr = npt.NDArray[np.uint8]

PATCH_M = 60.0  # side of the patches of ground whose tone changes as one
FEATHER_M = 6.0  # a changed patch blends into its neighbours over this
WARP_PATCH_M = 45.0  # feature size of the bends of the patches' borders
# Share of the ground whose tone changed after `years`: 1 - exp(-years / TONE_YEARS).
TONE_YEARS = 5.0
TONE_AMPLITUDE = 80.0  # grey levels of the curve's swing
TONE_PERIOD = 200.0  # grey levels of one period of the curve (slope 1 +- 2.5)
WATER_LEVEL = 0.09  # largest threshold offset of a water body (noise units), by 7 years
WATER_CELL_M = 900.0  # water bodies of one region rise and fall together
POND_CELL_M = 70.0  # feature size of small ponds
POND_THRESHOLD = 3.2  # ponds where the pond noise exceeds this (about 3 % of open land)
POND_SWING = 0.5  # how far a year moves the pond threshold (ponds fill and dry)
NOISE_STD = 1.74  # standard deviation of ``value_noise`` (measured over 4096 x 4096 px)


def years_since_reference(date: DateLook) -> float:
    """Years between the reference survey (date 0) and this one (0 on date 0)."""
    return max(0.0, float(int(date.label[:4]) - int(DATES[0].label[:4])))


def tone_changed_share(years: float) -> float:
    """Share of the ground whose tone changed ``years`` after the reference survey."""
    return 1.0 - math.exp(-years / TONE_YEARS)


def _patches(
    seed: int, x0: int, y0: int, size: int, gsd_m: float
) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], FloatImage]:
    """For each pixel: its patch's two uniform draws (changed?, which curve) and a weight
    falling to 0 over ``FEATHER_M`` at the patch's border (no seam where tones differ). Patches
    are ``PATCH_M`` squares in rows each shifted by its own amount (no straight columns)."""
    e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    s = (y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m  # metres south
    # Borders bent by a smooth displacement: patches are irregular, not squares.
    cell = WARP_PATCH_M / gsd_m
    bend_u = value_noise(key_of(seed, 0x7A6), x0 + 0.5, y0 + 0.5, size, cell) * (0.3 / NOISE_STD)
    bend_v = value_noise(key_of(seed, 0x7A7), x0 + 0.5, y0 + 0.5, size, cell) * (0.3 / NOISE_STD)
    v = s[:, None] / PATCH_M + bend_v
    rows = np.floor(v).astype(np.int64)
    shift = unit2(rows, rows * 0 + 7, key_of(seed, 0x7A0))
    u = e[None, :] / PATCH_M + shift + bend_u
    cols = np.floor(u).astype(np.int64)
    fu, fv = u - cols, v - rows
    edge = np.minimum(np.minimum(fu, 1.0 - fu), np.minimum(fv, 1.0 - fv)) * (PATCH_M / FEATHER_M)
    weight = np.clip(edge, 0.0, 1.0).astype(np.float32)
    weight = weight * weight * (3.0 - 2.0 * weight)
    return unit2(cols, rows, key_of(seed, 0x7A1)), unit2(cols, rows, key_of(seed, 0x7A2)), weight


def tone_mask(seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """0..1: how much of each pixel's tone changed since the reference survey. Nested: what
    changed by one date has changed by every later one (the same draw, a larger share)."""
    share = tone_changed_share(years_since_reference(date))
    if share <= 0.0:
        return np.zeros((size, size), np.float32)
    changed, _, weight = _patches(seed, x0, y0, size, gsd_m)
    mask: FloatImage = np.where(changed < share, weight, np.float32(0.0)).astype(np.float32)
    return mask


def tone_change(scene: Bgr, seed: int, date: DateLook, x0: int, y0: int, gsd_m: float) -> Bgr:
    """The scene with the tone of its changed patches passed through a non-monotonic curve
    (see the module docstring); the scene itself on the reference date."""
    share = tone_changed_share(years_since_reference(date))
    if share <= 0.0:
        return scene
    n = scene.shape[0]
    changed, curve, weight = _patches(seed, x0, y0, n, gsd_m)
    mask = np.where(changed < share, weight, np.float32(0.0)).astype(np.float32)
    if not mask.any():
        return scene
    img = scene.astype(np.float32)
    luma = img @ np.array((0.114, 0.587, 0.299), np.float32)
    # Each patch its own curve (its phase): uniform ground moves by one amount, no new edges.
    phase = (2.0 * math.pi * curve).astype(np.float32)
    arg = luma * np.float32(2.0 * math.pi / TONE_PERIOD) + phase
    delta = np.float32(TONE_AMPLITUDE) * mask * np.sin(arg)
    out: Bgr = np.clip(img + delta[:, :, None] + 0.5, 0, 255).astype(np.uint8)
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


def ponds(seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """0..1: small ponds standing on open land during this survey. The same hollows every
    year; how many hold water is the year's (wet years fill more, dry years leave them dry),
    departing from the reference survey's more the more years lie between."""
    k = key_of(seed, 0x7A4)
    hollow = value_noise(k, x0 + 0.5, y0 + 0.5, size, POND_CELL_M / gsd_m)
    swing = POND_SWING * min(1.0, years_since_reference(date) / 7.0)
    k_wet = key_of(seed, 0x7A5, date.index)
    wet = value_noise(k_wet, x0 + 0.5, y0 + 0.5, size, 4.0 * POND_CELL_M / gsd_m) / NOISE_STD
    thr = np.float32(POND_THRESHOLD) - np.float32(swing) * np.clip(wet, -1.5, 1.5)
    out: FloatImage = np.clip((hollow - thr) * np.float32(12.0), 0.0, 1.0)
    return out
