"""What people built on the ``farmland`` map: farmsteads and small towns (world metres).

Layers (:class:`Layers`) hold a window's colour, heights, the tree cover wanted where trees
grow and a land-cover code per pixel. Boxes and discs are painted with their exact box-filter
cover on each pixel (products of 1-D overlaps), computed from absolute positions only, so a
pixel gets the same value whatever window draws it. A farmstead stands in the outer corner of
some quarter sections (house, machine sheds, grain bins, a shelterbelt on its inner sides);
a town sits on the highway in some squares of 8 x 8 sections (a street grid, houses under
trees, a main street, a grain elevator). Buildings come and go between the surveys.
"""

from __future__ import annotations

import math

import numpy as np

from air_sitl.maps.procedural.canvas import Color, DateLook, shade
from air_sitl.maps.procedural.farmland_layout import (
    DITCH_HALF_M,
    FARMSTEAD_SHARE,
    HIGHWAY_EVERY,
    QUARTER_M,
    SECTION_M,
    grid_origin,
)
from air_sitl.maps.procedural.noise import FloatImage, rng_for, unit_of

# Land-cover codes of a pixel (``Layers.code``); crops use their crop code (0..4).
TREES, WATER, WETLAND, GRAVEL, PAVED, BUILDING, YARD, LAWN, FALLOW = 5, 6, 7, 8, 9, 10, 11, 12, 13
COVER_NAMES = (
    "corn", "soybeans", "winter wheat", "alfalfa", "grass", "trees", "water", "wetland",
    "gravel", "paved", "building", "farmyard", "lawn", "fallow",
)  # fmt: skip
GRAVEL_BGR: Color = (150, 170, 182)
ASPHALT_BGR: Color = (88, 88, 90)
_HOUSE_ROOFS: tuple[Color, ...] = (
    (70, 72, 76), (96, 100, 108), (58, 70, 100), (120, 120, 124), (60, 60, 62), (90, 84, 80),
)  # fmt: skip
_METAL_ROOFS: tuple[Color, ...] = (
    (206, 208, 206), (186, 190, 192), (60, 60, 150), (150, 120, 80), (90, 130, 90),
)  # fmt: skip
_BIN_BGR: Color = (196, 198, 200)
_LAWN = {"summer": (70, 128, 96), "autumn": (84, 130, 120), "spring": (86, 132, 124)}
TOWN_SECTIONS = 8  # at most one town in each square of 8 x 8 sections
BLOCK_M = 110.0  # town block pitch (street centre to street centre)
STREET_HALF_M = 8.0
YARD_SETBACK_M = DITCH_HALF_M + 4.0
DETAIL_MAX_GSD_M = 6.0  # coarser: buildings are below a pixel, yards and towns drawn as means


class Layers:
    """A window being drawn: colour, heights, wanted tree cover and its tree height, codes."""

    def __init__(self, x0: int, y0: int, size: int, gsd_m: float) -> None:
        self.x0, self.y0, self.size, self.gsd_m = x0, y0, size, gsd_m
        self.e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
        self.n = -(y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m
        self.col = np.zeros((size, size, 3), np.float32)
        self.height = np.zeros((size, size), np.float32)
        self.trees = np.zeros((size, size), np.float32)
        self.tree_h = np.zeros((size, size), np.float32)
        self.code = np.zeros((size, size), np.uint8)

    def paint(self, cover: FloatImage, color: Color | FloatImage, code: int) -> None:
        """Blend ``color`` over the whole window with ``cover`` (0..1)."""
        where = cover > 0.0
        if not where.any():
            return
        c = cover[where].astype(np.float32)[:, None]
        paint = np.asarray(color, np.float32)
        if paint.ndim == 3:
            paint = paint[where]
        self.col[where] = self.col[where] * (1.0 - c) + paint * c
        self.code[cover >= 0.5] = np.uint8(code)

    def _span(self, e0: float, e1: float, n0: float, n1: float) -> tuple[slice, slice] | None:
        g = self.gsd_m
        c0 = max(0, math.floor(e0 / g - 0.5) - self.x0)
        c1 = min(self.size, math.ceil(e1 / g + 0.5) - self.x0 + 1)
        r0 = max(0, math.floor(-n1 / g - 0.5) - self.y0)
        r1 = min(self.size, math.ceil(-n0 / g + 0.5) - self.y0 + 1)
        if c0 >= c1 or r0 >= r1:
            return None
        return slice(r0, r1), slice(c0, c1)

    def box(
        self,
        e0: float,
        e1: float,
        n0: float,
        n1: float,
        color: Color,
        code: int,
        height_m: float = 0.0,
        trees: tuple[float, float] | None = None,
    ) -> None:
        """Paint the box [e0, e1] x [n0, n1] (metres); raise it by ``height_m``; or, with
        ``trees`` (cover, height), ask for trees there instead of painting."""
        span = self._span(min(e0, e1), max(e0, e1), min(n0, n1), max(n0, n1))
        if span is None:
            return
        rows, cols = span
        g = self.gsd_m
        e, n = self.e[cols], self.n[rows]
        ce = np.clip(
            (np.minimum(e + g / 2, max(e0, e1)) - np.maximum(e - g / 2, min(e0, e1))) / g, 0, 1
        )
        cn = np.clip(
            (np.minimum(n + g / 2, max(n0, n1)) - np.maximum(n - g / 2, min(n0, n1))) / g, 0, 1
        )
        cover = (cn[:, None] * ce[None, :]).astype(np.float32)
        self._apply(rows, cols, cover, color, code, height_m, trees)

    def disc(
        self,
        ce: float,
        cn: float,
        r_m: float,
        color: Color,
        code: int,
        height_m: float,
        sun: tuple[float, float],
    ) -> None:
        """A grain bin seen from above: a disc with a conical roof lit from the sun's side."""
        span = self._span(ce - r_m, ce + r_m, cn - r_m, cn + r_m)
        if span is None:
            return
        rows, cols = span
        de = (self.e[cols] - ce)[None, :]
        dn = (self.n[rows] - cn)[:, None]
        dist = np.hypot(de, dn)
        cover = np.clip((r_m - dist) / self.gsd_m + 0.5, 0.0, 1.0).astype(np.float32)
        lit = (de * sun[0] + dn * sun[1]) / max(r_m, 1e-3)
        tone = (1.0 + 0.22 * lit)[:, :, None] * np.asarray(color, np.float32)
        self._apply(rows, cols, cover, tone.astype(np.float32), code, height_m, None)
        # The cone: highest in the middle.
        self.height[rows, cols] += (
            cover * 0.25 * height_m * np.clip(1.0 - dist / r_m, 0, 1)
        ).astype(np.float32)

    def _apply(
        self,
        rows: slice,
        cols: slice,
        cover: FloatImage,
        color: Color | FloatImage,
        code: int,
        height_m: float,
        trees: tuple[float, float] | None,
    ) -> None:
        if trees is not None:
            self.trees[rows, cols] = np.maximum(self.trees[rows, cols], trees[0] * cover)
            self.tree_h[rows, cols] = np.maximum(self.tree_h[rows, cols], trees[1] * (cover > 0))
            return
        c = cover[:, :, None]
        col = np.asarray(color, np.float32)
        self.col[rows, cols] = self.col[rows, cols] * (1.0 - c) + col * c
        self.code[rows, cols] = np.where(cover >= 0.5, np.uint8(code), self.code[rows, cols])
        if height_m:
            self.height[rows, cols] = np.maximum(self.height[rows, cols], height_m * (cover >= 0.5))
        # Whatever is painted over clears the trees asked for before.
        self.trees[rows, cols] *= 1.0 - cover

    def gabled(
        self,
        ce: float,
        cn: float,
        hw: float,
        hh: float,
        roof: Color,
        height_m: float,
        sun: tuple[float, float],
    ) -> None:
        """A gabled roof (ridge along the longer side), its two halves lit by the sun."""
        if hw >= hh:  # ridge east-west: north and south halves
            self.box(
                ce - hw, ce + hw, cn, cn + hh, shade(roof, 1.0 + 0.2 * sun[1]), BUILDING, height_m
            )
            self.box(
                ce - hw, ce + hw, cn - hh, cn, shade(roof, 1.0 - 0.2 * sun[1]), BUILDING, height_m
            )
        else:
            self.box(
                ce, ce + hw, cn - hh, cn + hh, shade(roof, 1.0 + 0.2 * sun[0]), BUILDING, height_m
            )
            self.box(
                ce - hw, ce, cn - hh, cn + hh, shade(roof, 1.0 - 0.2 * sun[0]), BUILDING, height_m
            )


def farmsteads(seed: int, lay: Layers, date: DateLook) -> None:
    """The farmsteads of the quarters the window reaches."""
    e0, n0 = grid_origin(seed)
    reach = YARD_SETBACK_M + 200.0
    qi0 = math.floor((lay.e[0] - reach - e0) / QUARTER_M)
    qi1 = math.floor((lay.e[-1] + reach - e0) / QUARTER_M)
    qj0 = math.floor((lay.n[-1] - reach - n0) / QUARTER_M)
    qj1 = math.floor((lay.n[0] + reach - n0) / QUARTER_M)
    for qi in range(qi0, qi1 + 1):
        for qj in range(qj0, qj1 + 1):
            if unit_of(seed, 0xFB8, qi, qj) < FARMSTEAD_SHARE and not in_town(seed, qi, qj):
                _farmstead(seed, lay, date, qi, qj, e0, n0)


def _farmstead(
    seed: int, lay: Layers, date: DateLook, qi: int, qj: int, e0: float, n0: float
) -> None:
    rng = rng_for(seed, 0xFB9, qi, qj)
    # The quarter's outer corner (on two section lines) and the directions into the quarter.
    sa, sb = (1.0, 1.0)
    ce = e0 + qi * QUARTER_M
    cn = n0 + qj * QUARTER_M
    if qi % 2:
        ce, sa = ce + QUARTER_M, -1.0
    if qj % 2:
        cn, sb = cn + QUARTER_M, -1.0
    size = float(rng.uniform(90.0, 150.0))
    s0 = YARD_SETBACK_M

    def at(u: float, v: float) -> tuple[float, float]:
        return ce + sa * u, cn + sb * v

    def box(u0: float, u1: float, v0: float, v1: float, col: Color, code: int, h: float = 0.0,
            trees: tuple[float, float] | None = None) -> None:  # fmt: skip
        (a0, b0), (a1, b1) = at(u0, v0), at(u1, v1)
        lay.box(a0, a1, b0, b1, col, code, h, trees)

    lawn = _LAWN[date.season]
    abandoned = rng.random() < 0.08 and date.index >= 2
    belt_w = float(rng.uniform(18.0, 32.0))
    if lay.gsd_m > DETAIL_MAX_GSD_M:
        box(s0, s0 + size, s0, s0 + size, shade(lawn, 1.05), YARD)
        box(s0 + size, s0 + size + belt_w, s0, s0 + size + belt_w, lawn, TREES, 0.0, (0.9, 13.0))
        box(s0, s0 + size, s0 + size, s0 + size + belt_w, lawn, TREES, 0.0, (0.9, 13.0))
        return
    box(s0, s0 + size, s0, s0 + size, lawn, LAWN)
    box(s0 + 0.15 * size, s0 + 0.95 * size, s0 + 0.1 * size, s0 + 0.8 * size, GRAVEL_BGR, YARD)
    drive = s0 + float(rng.uniform(0.3, 0.6)) * size
    box(0.0, s0 + 0.2 * size, drive - 2.5, drive + 2.5, GRAVEL_BGR, GRAVEL)
    belt_h = float(rng.uniform(10.0, 17.0))
    box(s0 + size, s0 + size + belt_w, s0, s0 + size + belt_w, lawn, TREES, 0.0, (0.95, belt_h))
    box(s0, s0 + size, s0 + size, s0 + size + belt_w, lawn, TREES, 0.0, (0.95, belt_h))
    box(s0, s0 + 0.35 * size, s0 + 0.75 * size, s0 + size, lawn, TREES, 0.0, (0.45, 9.0))
    sun = date.sun_dir()
    house_roof = _HOUSE_ROOFS[int(rng.integers(len(_HOUSE_ROOFS)))]
    hu, hv = s0 + float(rng.uniform(0.12, 0.3)) * size, s0 + float(rng.uniform(0.75, 0.9)) * size
    hw, hh = float(rng.uniform(5.0, 8.0)), float(rng.uniform(4.5, 6.5))
    sheds = [
        (
            s0 + float(rng.uniform(0.45, 0.85)) * size,
            s0 + float(rng.uniform(0.25, 0.65)) * size,
            float(rng.uniform(7.0, 12.0)),
            float(rng.uniform(12.0, 24.0)),
            rng.random() < 0.5,
            _METAL_ROOFS[int(rng.integers(len(_METAL_ROOFS)))],
            int(rng.random() < 0.15) * int(rng.integers(1, 3)),
        )
        for _ in range(int(rng.integers(1, 4)))
    ]
    n_bins = int(rng.integers(2, 7))
    bin_r = [float(rng.uniform(4.0, 7.5)) for _ in range(n_bins)]
    bins_born = 2 if rng.random() < 0.3 else 9
    if abandoned:
        return
    he, hn = at(hu, hv)
    lay.gabled(he, hn, hw, hh, house_roof, 6.5, sun)
    for su, sv, sw, sl, across, roof, born in sheds:
        if born > date.index:
            continue
        e, n = at(su, sv)
        w, h = (sl, sw) if across else (sw, sl)
        lay.gabled(e, n, w, h, roof, 7.5, sun)
    u = s0 + 0.2 * size
    for k, r in enumerate(bin_r):
        if k == n_bins - 1 and bins_born > date.index:
            break
        e, n = at(u + r, s0 + 0.15 * size + 8.0)
        lay.disc(e, n, r, _BIN_BGR, BUILDING, 1.6 * r + 4.0, sun)
        u += 2.0 * r + 2.5


def town_of(seed: int, ci: int, cj: int) -> tuple[float, float, float] | None:
    """The town of square (ci, cj) of 8 x 8 sections: (E, N) of its centre (a crossing of
    the highway and a section line) and its radius; None where there is none."""
    if unit_of(seed, 0xFBA, ci, cj) >= 0.8:
        return None
    e0, n0 = grid_origin(seed)
    phase = int(unit_of(seed, 0xFA2) * HIGHWAY_EVERY)
    first = ci * TOWN_SECTIONS
    line = first + (phase - first) % HIGHWAY_EVERY
    row = cj * TOWN_SECTIONS + 2 + int(unit_of(seed, 0xFBB, ci, cj) * 4)
    radius = 380.0 + 280.0 * unit_of(seed, 0xFBC, ci, cj)
    return e0 + line * SECTION_M, n0 + row * SECTION_M, radius


def towns_near(
    seed: int, e_lo: float, e_hi: float, n_lo: float, n_hi: float
) -> list[tuple[float, float, float]]:
    """The towns reaching the box."""
    cell = TOWN_SECTIONS * SECTION_M
    e0, n0 = grid_origin(seed)
    out = []
    for ci in range(math.floor((e_lo - e0) / cell) - 1, math.floor((e_hi - e0) / cell) + 1):
        for cj in range(math.floor((n_lo - n0) / cell) - 1, math.floor((n_hi - n0) / cell) + 1):
            t = town_of(seed, ci, cj)
            if t is not None and (
                t[0] + t[2] + BLOCK_M > e_lo and t[0] - t[2] - BLOCK_M < e_hi
                and t[1] + t[2] + BLOCK_M > n_lo and t[1] - t[2] - BLOCK_M < n_hi
            ):  # fmt: skip
                out.append(t)
    return out


def in_town(seed: int, qi: int, qj: int) -> bool:
    """Whether a quarter section's middle lies in a town (no farmstead there)."""
    e0, n0 = grid_origin(seed)
    e = e0 + (qi + 0.5) * QUARTER_M
    n = n0 + (qj + 0.5) * QUARTER_M
    return any(
        math.hypot(e - t[0], n - t[1]) < t[2] + QUARTER_M * 0.7
        for t in towns_near(seed, e, e, n, n)
    )


def town_blocks(town: tuple[float, float, float]) -> list[tuple[int, int]]:
    """The blocks (bx, by) of a town: those whose middle lies within its radius."""
    radius = town[2]
    k = math.ceil(radius / BLOCK_M) + 1
    return [
        (bx, by)
        for bx in range(-k, k)
        for by in range(-k, k)
        if math.hypot((bx + 0.5) * BLOCK_M, (by + 0.5) * BLOCK_M) < radius
    ]


def towns(seed: int, lay: Layers, date: DateLook) -> None:
    """The towns the window reaches: streets, lawns under trees, houses, main street, elevator."""
    for town in towns_near(seed, lay.e[0], lay.e[-1], lay.n[-1], lay.n[0]):
        ce, cn, _radius = town
        lawn = _LAWN[date.season]
        blocks = town_blocks(town)
        low = min(by for _bx, by in blocks)
        for bx, by in blocks:
            e0, n0 = ce + bx * BLOCK_M, cn + by * BLOCK_M
            if not (e0 - BLOCK_M < lay.e[-1] and e0 + 2 * BLOCK_M > lay.e[0]
                    and n0 - BLOCK_M < lay.n[0] and n0 + 2 * BLOCK_M > lay.n[-1]):  # fmt: skip
                continue
            lay.box(e0, e0 + BLOCK_M, n0, n0 + BLOCK_M, ASPHALT_BGR, PAVED)
            s = STREET_HALF_M
            main = bx in (-1, 0) and abs(by + 0.5) < 2.5
            elevator = bx == 0 and by == low
            ground = GRAVEL_BGR if elevator else (ASPHALT_BGR if main else lawn)
            lay.box(e0 + s, e0 + BLOCK_M - s, n0 + s, n0 + BLOCK_M - s, ground, LAWN)
            if lay.gsd_m > DETAIL_MAX_GSD_M:
                if not (main or elevator):
                    lay.box(e0 + s, e0 + BLOCK_M - s, n0 + s, n0 + BLOCK_M - s, lawn, TREES,
                            0.0, (0.5, 12.0))  # fmt: skip
                continue
            rng = rng_for(seed, 0xFBD, round(ce), round(cn), bx, by)
            sun = date.sun_dir()
            if elevator:
                _elevator(lay, rng, e0 + s, n0 + s, sun)
            elif main:
                _main_street(lay, rng, e0 + s, n0 + s, bx == 0, sun)
            else:
                _homes(lay, rng, e0 + s, n0 + s, date, sun)


def _homes(
    lay: Layers, rng: np.random.Generator, e0: float, n0: float, date: DateLook,
    sun: tuple[float, float],
) -> None:  # fmt: skip
    inner = BLOCK_M - 2 * STREET_HALF_M
    lay.box(
        e0, e0 + inner, n0, n0 + inner, (0, 0, 0), TREES, 0.0, (0.45, float(rng.uniform(9, 15)))
    )
    n_lots = int(rng.integers(4, 7))
    w = inner / n_lots
    for row in (0, 1):
        for i in range(n_lots):
            born = 1 + int(rng.integers(2)) if rng.random() < 0.06 else 0
            if born > date.index or rng.random() < 0.08:
                continue
            roof = _HOUSE_ROOFS[int(rng.integers(len(_HOUSE_ROOFS)))]
            hw, hh = float(rng.uniform(4.0, 0.38 * w)), float(rng.uniform(4.5, 7.5))
            e = e0 + (i + 0.5) * w + float(rng.uniform(-2, 2))
            setback = float(rng.uniform(9.0, 14.0)) + hh
            n = n0 + setback if row == 0 else n0 + inner - setback
            lay.gabled(e, n, hw, hh, roof, float(rng.uniform(5.5, 8.0)), sun)
            side = 1.0 if rng.random() < 0.5 else -1.0
            a = e + side * (hw + 2.0)
            b0, b1 = (n0, n - hh) if row == 0 else (n + hh, n0 + inner)
            lay.box(
                a - 1.6,
                a + 1.6,
                b0,
                b1,
                GRAVEL_BGR if rng.random() < 0.4 else (150, 152, 154),
                GRAVEL,
            )


def _main_street(
    lay: Layers, rng: np.random.Generator, e0: float, n0: float, east: bool,
    sun: tuple[float, float],
) -> None:  # fmt: skip
    inner = BLOCK_M - 2 * STREET_HALF_M
    n = n0
    front = e0 + 2.0 if east else e0 + inner - 2.0
    while n < n0 + inner - 8.0:
        depth, width = float(rng.uniform(20.0, 40.0)), float(rng.uniform(8.0, 20.0))
        width = min(width, n0 + inner - n)
        roof = _METAL_ROOFS[int(rng.integers(2))] if rng.random() < 0.5 else (112, 114, 116)
        a, b = (front, front + depth) if east else (front - depth, front)
        lay.box(a, b, n, n + width, shade(roof, float(rng.uniform(0.8, 1.1))), BUILDING, 7.0)
        n += width
    lot = (e0 + 45.0, e0 + inner - 2.0) if east else (e0 + 2.0, e0 + inner - 45.0)
    lay.box(lot[0], lot[1], n0 + 4.0, n0 + inner - 4.0, (120, 120, 122), PAVED)
    _ = sun


def _elevator(
    lay: Layers, rng: np.random.Generator, e0: float, n0: float, sun: tuple[float, float]
) -> None:
    inner = BLOCK_M - 2 * STREET_HALF_M
    lay.box(e0 + 20.0, e0 + 34.0, n0 + 30.0, n0 + 52.0, (176, 180, 182), BUILDING, 32.0)
    e = e0 + 44.0
    for _ in range(int(rng.integers(3, 6))):
        r = float(rng.uniform(7.0, 11.0))
        if e + r > e0 + inner:
            break
        lay.disc(e + r, n0 + 26.0, r, _BIN_BGR, BUILDING, 2.0 * r, sun)
        e += 2 * r + 3.0
