"""Where things are in the ``farmland`` map, and what each parcel grows in a given year.

Everything is a function of absolute UTM metres and the seed (no pixels, no window): the survey
grid of one-mile sections (``SECTION_M``) and their quarter sections, the section-line roads
(gravel, a paved highway on every ``HIGHWAY_EVERY``-th north-south line), the fields each
quarter is split into (a layout that may change in some year), the crop rotation of each
field, centre pivots (installed in some year, off in some years), the creek and the prairie
ponds and wetlands, whose water follows each year's wetness.

Land cover by year is explicit per parcel (:func:`crop_in`, :func:`pivot_running`,
:func:`wetness`): a survey's look follows from the year's crop, the previous year's residue
(spring) and the season, so generic year-gap effects can be keyed on parcels and years.
Arrays are separable where they can be: east positions per column, north per row.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.noise import FloatImage, key_of, unit2, unit_of, value_noise

SECTION_M = 1609.344  # one mile: the Public Land Survey's section
QUARTER_M = SECTION_M / 2.0  # a quarter section (160 acres)
GRAVEL_HALF_M = 3.6  # half width of a gravel section road
DITCH_HALF_M = 12.0  # the right of way (ditches, grass) each side of a road's centre line
HIGHWAY_EVERY = 6  # a paved highway on every 6th north-south section line (a township)
HIGHWAY_HALF_M = 3.7  # one lane
SHOULDER_M = 2.4
HIGHWAY_DITCH_HALF_M = 26.0
ROAD_SHARE = 0.88  # share of the section-line segments with a road
PIVOT_SHARE = 0.3  # share of the quarters irrigated by a centre pivot (Nebraska)
PIVOT_OFF_SHARE = 0.15  # share of the pivots not run in a given year
PASTURE_SHARE = 0.07  # quarters kept in pasture
FARMSTEAD_SHARE = 0.3  # quarters with a farmstead in their outer corner
RELAYOUT_FROM = 2010  # after the reference survey, a quarter's fields are laid out anew ...
RELAYOUT_EVERY_YEARS = 30.0  # ... in one year of its own among this many

# Crops (codes of :func:`crop_in`): the rotation tables below name them.
CORN, SOY, WHEAT, ALFALFA, GRASS = 0, 1, 2, 3, 4
CROP_NAMES = ("corn", "soybeans", "winter wheat", "alfalfa", "grass")
# Rotations (crop each year, repeating) and their cumulative shares.
_ROTATIONS = (
    ((CORN, SOY), 0.52),
    ((CORN, CORN, SOY), 0.64),
    ((CORN, SOY, WHEAT), 0.74),
    ((ALFALFA, ALFALFA, ALFALFA, ALFALFA, CORN, CORN), 0.83),
    ((CORN,), 0.88),
    ((GRASS, GRASS, GRASS, GRASS, GRASS, GRASS, GRASS, GRASS, CORN, SOY), 0.95),  # CRP ends
    ((GRASS,), 1.0),
)
_ROT_LEN = np.array([len(r) for r, _ in _ROTATIONS], dtype=np.int64)
_ROT_TABLE = np.array(
    [[r[i % len(r)] for i in range(int(_ROT_LEN.max()))] for r, _ in _ROTATIONS], dtype=np.int64
)
_ROT_SHARE = np.array([s for _, s in _ROTATIONS])

Ints = npt.NDArray[np.int64]
Floats = npt.NDArray[np.float64]


def band(d: Floats, half_m: float, gsd_m: float) -> Floats:
    """Share of a pixel (width ``gsd_m``) whose centre is ``d`` metres from a strip's centre
    line covered by the strip of half width ``half_m`` (an exact box filter across)."""
    lo = np.maximum(d - 0.5 * gsd_m, -half_m)
    hi = np.minimum(d + 0.5 * gsd_m, half_m)
    out: Floats = np.clip((hi - lo) / gsd_m, 0.0, 1.0)
    return out


class Grid(NamedTuple):
    """The survey grid over a window: 1-D per column (east) or per row (north)."""

    e: Floats  # pixel centres, east (columns)
    n: Floats  # pixel centres, north (rows)
    qi: Ints  # quarter-section column index (columns)
    qj: Ints  # quarter-section row index (rows)
    a: Floats  # metres east of the quarter's west edge (columns)
    b: Floats  # metres north of the quarter's south edge (rows)
    line_i: Ints  # nearest north-south section line (columns)
    du: Floats  # distance to it (columns)
    line_j: Ints  # nearest east-west section line (rows)
    dv: Floats  # distance to it (rows)


def grid(seed: int, x0: int, y0: int, size: int, gsd_m: float) -> Grid:
    """The survey grid over the window (x0, y0, size) of the lattice at ``gsd_m``."""
    e0, n0 = grid_origin(seed)
    e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    n = -(y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    u, v = (e - e0) / QUARTER_M, (n - n0) / QUARTER_M
    qi, qj = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    a, b = (u - qi) * QUARTER_M, (v - qj) * QUARTER_M
    li = np.round((e - e0) / SECTION_M).astype(np.int64)
    lj = np.round((n - n0) / SECTION_M).astype(np.int64)
    du = np.abs(e - e0 - li * SECTION_M)
    dv = np.abs(n - n0 - lj * SECTION_M)
    return Grid(e, n, qi, qj, a, b, li, du, lj, dv)


def grid_origin(seed: int) -> tuple[float, float]:
    """(E, N) of a section corner: the survey grid's offset from UTM's round numbers."""
    return SECTION_M * unit_of(seed, 0xFA0), SECTION_M * unit_of(seed, 0xFA1)


def is_highway(seed: int, line_i: Ints) -> npt.NDArray[np.bool_]:
    """Whether north-south section lines carry the paved highway."""
    phase = int(unit_of(seed, 0xFA2) * HIGHWAY_EVERY)
    out: npt.NDArray[np.bool_] = (line_i - phase) % HIGHWAY_EVERY == 0
    return out


def roads(seed: int, g: Grid, gsd_m: float) -> tuple[Floats, Floats, Floats]:
    """Cover (0..1, rows x columns) of gravel, of the highway's asphalt and of the roads'
    grassy right of way. A section-line road runs between two corners, or not at all."""
    sj = np.floor((g.n - grid_origin(seed)[1]) / SECTION_M).astype(np.int64)
    si = np.floor((g.e - grid_origin(seed)[0]) / SECTION_M).astype(np.int64)
    hwy = is_highway(seed, g.line_i)
    ns_on = (unit2(g.line_i[None, :], sj[:, None], key_of(seed, 0xFA3)) < ROAD_SHARE) | hwy
    ew_on = unit2(si[None, :], g.line_j[:, None], key_of(seed, 0xFA4)) < ROAD_SHARE
    ns_gravel = np.where(hwy, 0.0, band(g.du, GRAVEL_HALF_M, gsd_m))[None, :] * ns_on
    ew_gravel = band(g.dv, GRAVEL_HALF_M, gsd_m)[:, None] * ew_on
    paved = np.where(hwy, band(g.du, HIGHWAY_HALF_M + SHOULDER_M, gsd_m), 0.0)[None, :]
    paved = paved * np.ones_like(ew_gravel)
    ditch_ns = np.where(
        hwy, band(g.du, HIGHWAY_DITCH_HALF_M, gsd_m), band(g.du, DITCH_HALF_M, gsd_m)
    )
    ditch = np.maximum(ditch_ns[None, :] * ns_on, band(g.dv, DITCH_HALF_M, gsd_m)[:, None] * ew_on)
    gravel = np.maximum(ns_gravel, ew_gravel) * (1.0 - paved)
    return gravel, paved, ditch


class Fields(NamedTuple):
    """The fields over a window: one entry per field in ``key``, ``fid`` per pixel."""

    key: npt.NDArray[np.uint64]  # the identity (a hash) of each field
    fid: Ints  # per pixel (rows x columns): index of its field in ``key``
    edge_m: Floats  # distance to the field's nearest edge
    along_e: npt.NDArray[np.bool_]  # whether the field is longer east-west
    pivot: Floats  # 0..1 inside a centre pivot's circle (running or not)
    pivot_r_m: Floats  # distance from the pivot's centre (where a pivot stands)
    pasture: npt.NDArray[np.bool_]  # a quarter kept in pasture
    running: npt.NDArray[np.bool_]  # the quarter's pivot (if any) runs this year


def fields(seed: int, g: Grid, year: int, gsd_m: float) -> Fields:
    """The fields of every quarter in ``year``: whole, halves, forties or strips; a quarter's
    layout changes (fields split or merged) in one year of its own."""
    # Draws per quarter on the window's few quarters, then spread to the pixels.
    uqi, ii = np.unique(g.qi, return_inverse=True)
    uqj, jj = np.unique(g.qj, return_inverse=True)
    qi, qj = uqi[None, :], uqj[:, None]

    def spread(q: npt.NDArray[np.generic]) -> npt.NDArray[np.generic]:
        return q[jj][:, ii]

    k = key_of(seed, 0xFB0)
    changed = year >= 1990 + np.floor(unit2(qi, qj, k + 1) * 60.0)
    layout_q = np.floor(unit2(qi, qj, k + 2) * 5.0).astype(np.int64)
    later = np.floor(unit2(qi, qj, k + 3) * 5.0).astype(np.int64)
    layout_q = np.where(changed, later, layout_q)
    # Since the reference survey (2009) fields are split and merged more often: the NAIP
    # series of one North Dakota quad keeps 60 % of its strongest edges over 3-4 years, 52 %
    # over 7 (docs/map-dates.md).
    again = year >= RELAYOUT_FROM + np.floor(unit2(qi, qj, k + 8) * RELAYOUT_EVERY_YEARS)
    layout_q = np.where(again, np.floor(unit2(qi, qj, k + 9) * 5.0).astype(np.int64), layout_q)
    kind = unit2(qi, qj, k + 5)
    pivot_from = 1985 + np.floor(unit2(qi, qj, k + 6) * 45.0)
    pivot_q = (kind < PIVOT_SHARE) & (year >= pivot_from)
    pasture_q = (kind >= PIVOT_SHARE) & (kind < PIVOT_SHARE + PASTURE_SHARE)
    # Field keys: (quarter, field index 0..3, layout); a pivot's circle is one field.
    nq = uqj.size * uqi.size
    f4 = np.arange(4, dtype=np.int64)
    fk = unit2(qi[:, :, None] * 8 + f4, (qj * 8 + layout_q)[:, :, None] + 0 * f4, k + 4)
    fk = np.where(pivot_q[:, :, None], unit2(qi, qj, k + 7)[:, :, None] + 0 * f4, fk)
    keys = (fk.reshape(nq * 4) * 2.0**53).astype(np.uint64)
    layout = spread(layout_q)
    is_pivot = spread(pivot_q).astype(bool)
    a, b = g.a[None, :], g.b[:, None]
    half = QUARTER_M / 2.0
    third = QUARTER_M / 3.0
    # Field index and its extent (a0, a1, b0, b1) by layout: 0 whole, 1 east/west halves,
    # 2 north/south halves, 3 forties, 4 three strips north-south.
    ea, eb = (a >= half) * np.ones_like(b, bool), (b >= half) * np.ones_like(a, bool)
    strip = np.minimum(np.floor(a / third), 2.0) * np.ones_like(b)
    by_e = (layout == 1) | (layout == 3)
    by_n = (layout == 2) | (layout == 3)
    f = np.where(by_e, ea, 0) + np.where(by_n, 2 * eb, 0) + np.where(layout == 4, strip, 0)
    f = np.where(layout == 2, eb, f).astype(np.int64)
    a0 = np.where(by_e, ea * half, np.where(layout == 4, strip * third, 0.0))
    a1 = np.where(by_e, half + ea * half, np.where(layout == 4, (strip + 1) * third, QUARTER_M))
    b0 = np.where(by_n, eb * half, 0.0)
    b1 = np.where(by_n, half + eb * half, QUARTER_M)
    edge = np.minimum(np.minimum(a - a0, a1 - a), np.minimum(b - b0, b1 - b))
    fid = (jj[:, None] * uqi.size + ii[None, :]) * 4 + f
    r = np.hypot(a - half, b - half)
    pivot_r = QUARTER_M / 2.0 - 14.0
    inside = np.clip((pivot_r - r) / gsd_m + 0.5, 0.0, 1.0) * is_pivot
    edge = np.where(is_pivot, np.abs(pivot_r - r), edge)
    along = np.where(is_pivot, True, (a1 - a0) >= (b1 - b0))
    pasture = spread(pasture_q).astype(bool)
    running = spread(pivot_running(seed, qi, qj, year)).astype(bool)
    return Fields(keys, fid, edge, along, inside, np.where(is_pivot, r, np.inf), pasture, running)


def crop_in(seed: int, field_key: npt.NDArray[np.uint64], year: int) -> Ints:
    """The crop (CORN, SOY, ...) each field grows in ``year``: its rotation at its phase."""
    u = unit2(field_key.astype(np.int64), np.zeros_like(field_key, np.int64), key_of(seed, 0xFC0))
    rot = np.searchsorted(_ROT_SHARE, u, side="right").clip(0, len(_ROT_SHARE) - 1)
    phase = np.floor(unit2(field_key.astype(np.int64), rot, key_of(seed, 0xFC1)) * 10.0)
    idx = (year + phase.astype(np.int64)) % _ROT_LEN[rot]
    out: Ints = _ROT_TABLE[rot, idx]
    return out


def field_unit(seed: int, field_key: npt.NDArray[np.uint64], year: int | Ints, salt: int) -> Floats:
    """A uniform draw per field and year (harvested yet, tilled, row direction, ...);
    ``year`` may be one per field."""
    z = np.zeros_like(field_key, np.int64)
    return unit2(field_key.astype(np.int64), z + year, key_of(seed, 0xFC2, salt))


def pivot_running(seed: int, qi: Ints, qj: Ints, year: int) -> npt.NDArray[np.bool_]:
    """Whether each quarter's pivot is run in ``year`` (some stand idle a year: dry circles)."""
    out: npt.NDArray[np.bool_] = unit2(qi, qj, key_of(seed, 0xFC3, year)) >= PIVOT_OFF_SHARE
    return out


def wetness(seed: int, year: int) -> float:
    """How wet ``year`` left the ground (0 drought .. 1 flooded): the year's weather over the
    region, one draw per year (potholes fill to their level, the creek widens)."""
    return 0.15 + 0.7 * unit_of(seed, 0xFD0, year)


BASIN_MEMORY_YEARS = 3  # a pothole's water is the wetness of this many years (its own and before)


def basin_wetness(seed: int, year: int) -> float:
    """How full the potholes and the creek stand in ``year``: the mean wetness of
    ``BASIN_MEMORY_YEARS`` years up to it. Basins fill over wet years and draw down slowly: in
    the NAIP series of one North Dakota quarter quad (2009-2020) 94-99 % of a survey's open
    water is water in any later one, and the drought year 2012 had more than 2009."""
    years = range(year - BASIN_MEMORY_YEARS + 1, year + 1)
    return sum(wetness(seed, y) for y in years) / BASIN_MEMORY_YEARS


def hills(seed: int, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """The broadest octave of the bare terrain the built-in surface raises (about -1 on the
    valley floors .. 1 on the hilltops): where the soil is eroded light."""
    _amp, cell_m, _octaves = TERRAIN
    out: FloatImage = value_noise(key_of(seed, 0x7E44), x0, y0, size, cell_m / gsd_m)
    return out


TERRAIN = (8.0, 1500.0, 3)  # amplitude m, cell m, octaves


CREEK_BAND_M = 6.0 * SECTION_M  # at most one creek in each band this wide (running north)
CREEK_SHARE = 0.7
# The creek's meander: wavelengths (m) and amplitudes (m) of its sideways swings.
_MEANDERS = ((5200.0, 520.0), (1900.0, 200.0), (700.0, 70.0), (260.0, 18.0))


def creek_distance_m(seed: int, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """Distance (m, across its course) to the nearest creek's centre line (large where none).

    Creeks run north-south, meandering; one at most per band of ``CREEK_BAND_M``."""
    e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    n = -(y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
    reach = sum(a for _w, a in _MEANDERS)
    best = np.full((size, size), 1e9)
    for k in range(
        math.floor((e[0] - reach) / CREEK_BAND_M), math.floor((e[-1] + reach) / CREEK_BAND_M) + 1
    ):
        if unit_of(seed, 0xFE0, k) >= CREEK_SHARE:
            continue
        centre = (k + 0.25 + 0.5 * unit_of(seed, 0xFE1, k)) * CREEK_BAND_M + np.zeros_like(n)
        slope = np.zeros_like(n)
        for m, (wave, amp) in enumerate(_MEANDERS):
            w = 2.0 * math.pi / wave
            phase = 2.0 * math.pi * unit_of(seed, 0xFE2, k, m)
            centre += amp * np.sin(w * n + phase)
            slope += amp * w * np.cos(w * n + phase)
        d = np.abs(e[None, :] - centre[:, None]) / np.sqrt(1.0 + slope * slope)[:, None]
        best = np.minimum(best, d)
    out: FloatImage = best.astype(np.float32)
    return out


DRAIN_CELL_M = 220.0  # feature size of the swells between the fields' drainage lines
DRAIN_SLOPE = 2.5  # median slope of value_noise, per cell: |noise| * cell / slope ~ metres
SWALE_HALF_M = 40.0  # the swale each side of a drainage line: lower, wetter, darker soil
WATERWAY_HALF_M = 6.0  # a grassed waterway along the line (NRCS code 412: 8-20 m wide)
WATERWAY_SHARE = 0.7  # share of the drainage lines' length with a grassed waterway


def drainage(seed: int, x0: int, y0: int, size: int, gsd_m: float) -> tuple[Floats, Floats]:
    """The relief inside the fields, the same every year: (swale 0..1, how near and low a
    drainage line's swale is; waterway 0..1, cover of the grassed waterway kept in grass
    along the line where one was built)."""
    line = value_noise(key_of(seed, 0xFE6), x0 + 0.5, y0 + 0.5, size, DRAIN_CELL_M / gsd_m)
    d = np.abs(line).astype(np.float64) * (DRAIN_CELL_M / DRAIN_SLOPE)  # metres off the line
    swale: Floats = np.exp(-((2.0 * d / SWALE_HALF_M) ** 2))  # smooth across the line
    built = value_noise(key_of(seed, 0xFE7), x0 + 0.5, y0 + 0.5, size, 700.0 / gsd_m)
    waterway: Floats = band(d, WATERWAY_HALF_M, gsd_m) * (built > -0.52 * 1.74)
    return swale, waterway


def pothole(seed: int, x0: int, y0: int, size: int, gsd_m: float) -> FloatImage:
    """Depth index of the prairie potholes: > 0 in a basin, deeper toward its middle."""
    p = value_noise(key_of(seed, 0xFE3), x0 + 0.5, y0 + 0.5, size, 230.0 / gsd_m)
    p += 0.45 * value_noise(key_of(seed, 0xFE4), x0 + 0.5, y0 + 0.5, size, 70.0 / gsd_m)
    region = value_noise(key_of(seed, 0xFE5), x0 + 0.5, y0 + 0.5, size, 3000.0 / gsd_m)
    out: FloatImage = (p + 0.35 * region - 2.9).astype(np.float32)
    return out


def water_level(wet: float) -> float:
    """Pothole depth index above which a basin holds open water in a year this wet (a dry
    year: only the deepest middles, or none)."""
    return 1.55 - 1.4 * wet


def year_of(label: str) -> int:
    """The year of a survey's ISO date label."""
    return int(label[:4])
