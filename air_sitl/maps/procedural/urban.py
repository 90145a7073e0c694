"""The ``urban`` map: a street grid of varied blocks (houses, commercial, parks, parking).

Layout lives in a frame rotated by a seed-chosen angle from UTM; streets sit at jittered
multiples of the block pitch, so every block is found from its indices alone and any tile is
drawn without its neighbours. Per-block random choices never depend on the date: dates only
switch buildings on or off, change colours, sun and tree size.
What stands in a block (homes, shops, parks, parking) is laid out in ``urban_blocks``;
this module places the streets and draws (``draw``) and raises (``objects``) it all.
"""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np

from air_sitl.maps.procedural.canvas import (
    DATES,
    Canvas,
    Color,
    DateLook,
    Point,
    finish,
    shade,
)
from air_sitl.maps.procedural.noise import (
    key_of,
    rng_for,
    unit_of,
    value_noise,
    white_noise,
)
from air_sitl.maps.procedural.survey import lean_per_m
from air_sitl.maps.procedural.urban_blocks import (
    Block,
    box,
    fill_block,
    grown,
    ridge_band,
)
from air_sitl.maps.procedural.urban_dates import (
    CONIFER_INDEX,
    MARKING_M,
    autumn_crown,
    bare_crown,
    construction_site,
    crop_index,
    developed_at,
    is_fields,
    new_paving,
    parked_car,
    paved_at,
    rebuilt_at,
)
from air_sitl.maps.procedural.urban_draw import draw_roof, erase_circle, erase_shadow
from air_sitl.maps.procedural.urban_draw import hull as convex_hull
from air_sitl.maps.procedural.urban_years import (
    field_texture,
    object_look,
    reroofed,
    street_stretches,
)
from air_sitl.maps.procedural.yeargap import renewed_noise

PITCH_M = 105.0
FINE_TEXTURE = 0.06  # relative amplitude of the 0.3-1 m material texture
GRAIN_DN = 9.0  # per-pixel grain (uniform amplitude, grey levels) at 0.6 m
FIELDS_BELOW = -0.35  # districts below this (a 1.5 km noise) turn to farm fields
_ASPHALT: Color = (86, 85, 84)
_ASPHALT_NEW: Color = (52, 51, 50)
_LOT_NEW: Color = (70, 70, 72)  # a new parking lot's fresh asphalt
_SIDEWALK: Color = (158, 166, 172)
_DRIVEWAY: Color = (140, 146, 150)
_DIRT: Color = (92, 118, 142)
_POOL: Color = (205, 175, 90)
_VERGE: Color = (84, 122, 104)
# Crops by season: green cereal, ripe cereal, bare soil, maize or beet, grass, rape or hay.
_CROPS = {
    "summer": (
        (62, 138, 110),
        (96, 176, 206),
        (86, 112, 140),
        (48, 112, 66),
        (78, 150, 118),
        (80, 196, 220),
    ),
    "autumn": (
        (72, 124, 112),
        (126, 168, 190),
        (64, 86, 112),
        (60, 100, 90),
        (84, 140, 122),
        (58, 78, 100),
    ),
    "spring": (
        (78, 150, 112),
        (70, 104, 130),
        (80, 104, 132),
        (74, 98, 122),
        (88, 154, 128),
        (64, 186, 214),
    ),
}
_LAWN = {"summer": (64, 116, 92), "autumn": (80, 126, 134), "spring": (78, 108, 114)}
_TREE = {
    "summer": ((34, 74, 44), (40, 86, 58), (30, 64, 38)),
    # Autumn: each broadleaf its own colour (``autumn_crown``); the evergreens stay green.
    "autumn": ((40, 92, 164), (48, 140, 176), (72, 92, 40)),
    "spring": ((78, 92, 104), (70, 84, 92), (60, 104, 84)),
}


class UrbanWorld:
    """The urban generator for one seed and gsd."""

    def __init__(self, seed: int) -> None:
        self.seed = seed
        self.angle_rad = math.radians(35.0 * unit_of(seed, 77))
        self.c = math.cos(self.angle_rad)
        self.s = math.sin(self.angle_rad)

    # Layout frame (u, v) <-> world (E, N): a rotation about the UTM origin.
    def to_world(self, pts: list[Point] | tuple[Point, ...]) -> list[Point]:
        """Layout points to world metres."""
        c, s = self.c, self.s
        return [(c * u - s * v, s * u + c * v) for u, v in pts]

    def street(self, axis: int, k: int) -> tuple[float, float, bool]:
        """Centre position, half width and 'main road' flag of street ``k`` along an axis."""
        u = unit_of(self.seed, 11, axis, k)
        main = k % 5 == 0
        return (k * PITCH_M + (u - 0.5) * 0.45 * PITCH_M, 10.0 if main else 6.0, main)

    def resurfaced_at(self, axis: int, k: int) -> int:
        """Date index from which street k has fresh asphalt (3 = never)."""
        u = unit_of(self.seed, 12, axis, k)
        return 1 if u < 0.15 else 2 if u < 0.3 else 3

    @functools.lru_cache(maxsize=4096)  # noqa: B019 - one world per map, bounded cache
    def block(self, kx: int, ky: int, d: int = 0) -> Block:
        """The content of block (kx, ky) at date index ``d``: as first built, or after its
        redevelopment (a construction site the survey it is caught in, half the time); with
        the new street or parking lot it has been given by then."""
        built = self._built_block(kx, ky, d)
        if d < paved_at(self.seed, kx, ky):
            return built
        return new_paving(self.seed, kx, ky, built)

    def _built_block(self, kx: int, ky: int, d: int) -> Block:
        """Block (kx, ky) at date index ``d`` as first built or redeveloped; fields at the
        town's edge built over (a new subdivision between new streets)."""
        base = self._first_block(kx, ky)
        if is_fields(base):
            at = developed_at(self.seed, kx, ky)
            # A field given a new street or lot before is not built over: it would move.
            if d < at or paved_at(self.seed, kx, ky) < at or not self._at_town_edge(kx, ky):
                return base
            rng = rng_for(self.seed, 25, kx, ky, at)
            bounds, kind = self._street_bounds(kx, ky), 0.62 * rng.random()  # homes
        else:
            at = rebuilt_at(self.seed, kx, ky)
            if d < at:
                return base
            rng = rng_for(self.seed, 24, kx, ky, at)
            bounds, kind = base.bounds, 0.3 + 0.7 * rng.random()
        site = rng.random() < 0.5
        if d == at and site:
            return construction_site(rng, *bounds)
        return fill_block(rng, kind, *bounds)

    def in_fields(self, e: float, n: float) -> bool:
        """Whether world point (E, N) lies in a block of farm fields (the town's outskirts)
        as the first survey found it."""
        u, v = self.c * e + self.s * n, -self.s * e + self.c * n
        kx, ky = math.floor(u / PITCH_M), math.floor(v / PITCH_M)
        for i in (kx - 1, kx, kx + 1):  # streets are jittered: the block may be a neighbour
            for j in (ky - 1, ky, ky + 1):
                blk = self._first_block(i, j)
                u0, v0, u1, v1 = blk.bounds
                if u0 <= u <= u1 and v0 <= v <= v1:
                    return is_fields(blk)
        return False

    def _at_town_edge(self, kx: int, ky: int) -> bool:
        """Whether a block has a built (not field) block beside it."""
        around = ((kx - 1, ky), (kx + 1, ky), (kx, ky - 1), (kx, ky + 1))
        return any(not is_fields(self._first_block(i, j)) for i, j in around)

    def _street_bounds(self, kx: int, ky: int) -> tuple[float, float, float, float]:
        """(u0, v0, u1, v1) of block (kx, ky) between its four streets' kerbs."""
        ux0, wx0, _ = self.street(0, kx)
        ux1, wx1, _ = self.street(0, kx + 1)
        vy0, wy0, _ = self.street(1, ky)
        vy1, wy1, _ = self.street(1, ky + 1)
        return ux0 + wx0, vy0 + wy0, ux1 - wx1, vy1 - wy1

    @functools.lru_cache(maxsize=4096)  # noqa: B019 - one world per map, bounded cache
    def _first_block(self, kx: int, ky: int) -> Block:
        """The content of block (kx, ky) as the first survey found it."""
        ux0, _, main_x0 = self.street(0, kx)
        ux1, _, main_x1 = self.street(0, kx + 1)
        vy0, _, main_y0 = self.street(1, ky)
        vy1, _, main_y1 = self.street(1, ky + 1)
        u0, v0, u1, v1 = self._street_bounds(kx, ky)
        rng = rng_for(self.seed, 21, kx, ky)
        # Districts: a smooth field (1.5 km) shifts blocks between homes, shops and parks.
        zone = float(
            value_noise(
                key_of(self.seed, 22), (u0 + u1) / 2 / 1500.0, (v0 + v1) / 2 / 1500.0, 1, 1.0
            )[0, 0]
        )
        kind = float(np.clip(rng.random() + 0.12 * zone, 0.0, 0.999))
        # Out of town (low districts): farm fields, mixed with the last houses at the edge.
        fields = unit_of(self.seed, 23, kx, ky) < (FIELDS_BELOW - zone) / 0.5
        if fields:  # fields reach over the minor streets to their middle: only main roads stay
            u0, u1 = (u0 if main_x0 else ux0), (u1 if main_x1 else ux1)
            v0, v1 = (v0 if main_y0 else vy0), (v1 if main_y1 else vy1)
        return fill_block(rng, kind, u0, v0, u1, v1, fields)

    def _layout_corners(self, cv: Canvas) -> tuple[list[float], list[float]]:
        """Layout-frame (u, v) of the tile's four corners: its rotated bounding box."""
        corners = [
            (cv.e_min, cv.n_min),
            (cv.e_max, cv.n_min),
            (cv.e_min, cv.n_max),
            (cv.e_max, cv.n_max),
        ]
        us = [self.c * e + self.s * n for e, n in corners]
        vs = [-self.s * e + self.c * n for e, n in corners]
        return us, vs

    def draw(self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook) -> np.ndarray:
        """One BGR tile of ``size`` pixels at absolute lattice (x0, y0)."""
        cv = Canvas(x0, y0, size, gsd_m, _ASPHALT)
        # Layout-frame range of the tile (its rotated bounding box) plus shadow margin.
        us, vs = self._layout_corners(cv)
        margin = 45.0
        kx0 = math.floor((min(us) - margin) / PITCH_M) - 1
        kx1 = math.floor((max(us) + margin) / PITCH_M) + 1
        ky0 = math.floor((min(vs) - margin) / PITCH_M) - 1
        ky1 = math.floor((max(vs) + margin) / PITCH_M) + 1
        u_lo, u_hi = min(us) - margin, max(us) + margin
        v_lo, v_hi = min(vs) - margin, max(vs) + margin
        self._draw_roads(cv, date, kx0, kx1, ky0, ky1, u_lo, u_hi, v_lo, v_hi)
        d = date.index
        blocks = [
            self.block(kx, ky, d)
            for ky in range(ky0, ky1 + 1)
            for kx in range(kx0, kx1 + 1)
            if _box_overlaps(self.block(kx, ky, d).bounds, u_lo, v_lo, u_hi, v_hi)
        ]
        lawn = _LAWN[date.season]
        tree_cols = _TREE[date.season]
        crops = _CROPS[date.season]
        fields: list[list[Point]] = []  # crop fields: their texture is the year's own
        for blk in blocks:
            for poly, kind in blk.grounds:
                if kind.startswith("crop"):
                    fields.append(self.to_world(poly))
                    cv.poly(fields[-1], crops[crop_index(self.seed, date, poly, kind)])
                    cv.poly(fields[-1], (40,), "veg")
                    continue
                col = {
                    "sidewalk": _SIDEWALK,
                    "lawn": lawn,
                    "parking": (92, 93, 95),
                    "driveway": _DRIVEWAY,
                    "pool": _POOL,
                    "dirt": _DIRT,
                    "path": (150, 162, 170),
                    "verge": _VERGE,
                    "newroad": _ASPHALT_NEW,
                    "newlot": _LOT_NEW,
                }[kind]
                col = object_look(self.seed, date, kind, poly[0], col)
                cv.poly(self.to_world(poly), col)
                if kind in ("lawn", "verge"):
                    cv.poly(self.to_world(poly), (70,), "veg")
            for b in blk.buildings:
                if b.born > d:
                    # A construction site the date before it is finished.
                    if b.born == d + 1:
                        cv.poly(self.to_world(grown(b.corners, 2.0)), _DIRT)
                    continue
                if b.gone <= d:
                    cv.poly(self.to_world(b.corners), _DIRT if b.gone == d else lawn)
            paint = [self.to_world(line) for line, w in blk.paint if w < MARKING_M]
            cv.segments([(w[0], w[1]) for w in paint], (225, 228, 230), 0.15)
            for line, width in blk.paint:  # new streets' markings, wider than stall lines
                if width >= MARKING_M:
                    w = self.to_world(line)
                    cv.segments([(w[0], w[1])], (220, 222, 224), width)
            if gsd_m <= 1.5:  # cars vanish into the lot's grey on coarse levels
                for poly, _col in blk.cars:
                    car = parked_car(self.seed, date, poly)
                    if car is not None:
                        cv.poly(self.to_world(poly), car)
        sun_e, sun_n = date.sun_dir()
        # Shadows of buildings and trees.
        for blk in blocks:
            for b in blk.buildings:
                if b.born <= d < b.gone:
                    dx, dy = date.shadow_vector(b.height_m)
                    world = self.to_world(b.corners)
                    moved = [(e + dx, n + dy) for e, n in world]
                    hull = convex_hull(world + moved)
                    cv.poly(hull, (255,), "shadow")
            for c, r, ci, born in blk.trees:
                if born <= d:
                    rr = r * (1.0 + 0.12 * (d - born))
                    dx, dy = date.shadow_vector(rr * 1.6)
                    (e, n) = self.to_world([c])[0]
                    bare = date.leaf_off and ci != CONIFER_INDEX
                    cv.circle((e + dx, n + dy), rr * 0.95, (110 if bare else 255,), "shadow")
        cv.shadow = np.ascontiguousarray(cv.shadow)
        # Roofs and tree crowns above the shadows.
        roof_shadow = np.zeros_like(cv.shadow)
        for blk in blocks:
            for b in (reroofed(self.seed, date, b) for b in blk.buildings if b.born <= d < b.gone):
                world = self.to_world(b.corners)
                le, ln = lean_per_m(self.seed, date, *world[0])
                lean = (le * b.height_m, ln * b.height_m)
                if lean != (0.0, 0.0):  # walls show between the footprint and the roof
                    roof_at = [(e + lean[0], n + lean[1]) for e, n in world]
                    cv.poly(convex_hull(world + roof_at), shade(b.roof, 0.55))
                    world = roof_at
                erase_shadow(cv, world, roof_shadow)
                draw_roof(cv, self.to_world, b, world, sun_e, sun_n, lean)
            for c, r, ci, born in blk.trees:
                if born <= d:
                    rr = r * (1.0 + 0.12 * (d - born))
                    (e, n) = self.to_world([c])[0]
                    le, ln = lean_per_m(self.seed, date, e, n)
                    e, n = e + le * rr * 1.6, n + ln * rr * 1.6
                    if date.leaf_off and ci != CONIFER_INDEX:
                        bare_crown(cv, self.seed, (e, n), rr)
                        continue
                    col = tree_cols[ci % len(tree_cols)]
                    if date.season == "autumn" and ci != CONIFER_INDEX:
                        col = autumn_crown(self.seed, c)
                    cv.circle((e, n), rr, shade(col, 0.8))
                    cv.circle((e + sun_e * rr * 0.25, n + sun_n * rr * 0.25), rr * 0.7, col)
                    cv.circle((e, n), rr, (255,), "veg")
                    erase_circle(cv, (e, n), rr * 0.9)
        key = key_of(self.seed, 31)
        px_m = 1.0 / gsd_m
        texture = 0.07 * renewed_noise(
            key, self.seed, date, x0, y0, size, 8.0 * px_m, 3, coarse_octaves=1
        )
        field_texture(cv, self.seed, date, fields, texture, 8.0 * px_m)
        # Materials at 0.3-1 m (gravel, asphalt, roof tiles, grass tufts): the fine texture
        # of real 0.5 m imagery; the grain is each survey's own (film, sensor, processing).
        texture += FINE_TEXTURE * renewed_noise(
            key + 3, self.seed, date, x0, y0, size, 0.7 * px_m, 2
        )
        veg_tex = 0.22 * renewed_noise(key + 5, self.seed, date, x0, y0, size, 1.6 * px_m, 2)
        date_key = key_of(self.seed, 32, date.index)
        grain = float(GRAIN_DN * min(1.0, 0.6 * px_m)) * white_noise(date_key, x0, y0, size)
        return finish(cv, texture, grain, 0.5, veg_tex)

    def objects(self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook) -> np.ndarray:
        """Heights above the terrain (float32 m) of one tile: roofs and tree crowns.

        The same buildings and trees as :meth:`draw` at the same date: a roof where a house
        is drawn (gabled roofs rise 1.5 m to the ridge), a dome where a crown is drawn.
        """
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        out = np.zeros((size, size), dtype=np.float32)
        us, vs = self._layout_corners(cv)
        margin = 10.0
        u_lo, u_hi = min(us) - margin, max(us) + margin
        v_lo, v_hi = min(vs) - margin, max(vs) + margin
        d = date.index
        # Painted from low to high: where objects overlap, the highest shows (a maximum).
        circles: list[tuple[float, int, tuple[tuple[int, int], int]]] = []
        polys: list[tuple[float, int, np.ndarray]] = []
        for ky in range(math.floor(v_lo / PITCH_M) - 1, math.floor(v_hi / PITCH_M) + 2):
            for kx in range(math.floor(u_lo / PITCH_M) - 1, math.floor(u_hi / PITCH_M) + 2):
                blk = self.block(kx, ky, d)
                if not _box_overlaps(blk.bounds, u_lo, v_lo, u_hi, v_hi):
                    continue
                for c, r, _ci, born in blk.trees:
                    if born <= d:
                        rr = r * (1.0 + 0.12 * (d - born))
                        p = cv.px(self.to_world([c]))[0]
                        top = rr * 1.6 + 1.5
                        # A crown: a dome of rings, lower toward the rim.
                        for frac, hgt in ((1.0, 0.6), (0.75, 0.85), (0.45, 1.0)):
                            rad = max(1, round(rr * frac / gsd_m * 16))
                            circles.append((top * hgt, 0, ((int(p[0]), int(p[1])), rad)))
                for b in blk.buildings:
                    if not b.born <= d < b.gone:
                        continue
                    polys.append((b.height_m, 1, cv.px(self.to_world(b.corners))))
                    if b.gabled:
                        # The ridge band (the middle half across the ridge), 1.5 m higher.
                        p = b.corners
                        if b.ridge_along_x:  # ridge from mid(p0, p3) to mid(p1, p2)
                            band = ridge_band(p[0], p[3], p[1], p[2])
                        else:  # ridge from mid(p0, p1) to mid(p3, p2)
                            band = ridge_band(p[0], p[1], p[3], p[2])
                        polys.append((b.height_m + 1.5, 1, cv.px(self.to_world(band))))
        # One order for both kinds (by height, crowns before roofs at equal heights).
        order = sorted(
            [(h, k, i) for i, (h, k, _c) in enumerate(circles)]
            + [(h, k, i) for i, (h, k, _p) in enumerate(polys)]
        )
        for height, kind, i in order:
            if kind == 0:
                centre, rad = circles[i][2]
                cv2.circle(out, centre, rad, (height,), -1, cv2.LINE_8, 4)
            else:
                cv2.fillPoly(out, [polys[i][2]], (height,), cv2.LINE_8, 4)
        # Polygon edges drawn without anti-aliasing (float layers) would show as stairs along
        # roof edges seen closer than a pixel; a 3-tap blur spreads each edge over a pixel.
        return np.asarray(cv2.GaussianBlur(out, (3, 3), 0.0, borderType=cv2.BORDER_REPLICATE))

    def _draw_roads(
        self,
        cv: Canvas,
        date: DateLook,
        kx0: int,
        kx1: int,
        ky0: int,
        ky1: int,
        u_lo: float,
        u_hi: float,
        v_lo: float,
        v_hi: float,
    ) -> None:
        """Resurfaced stretches and lane markings of every street crossing the tile."""
        d = date.index
        for axis, k0, k1 in ((0, kx0, kx1), (1, ky0, ky1)):
            for k in range(k0, k1 + 2):
                pos, half, main = self.street(axis, k)
                new = self.resurfaced_at(axis, k) <= d
                lo, hi = (v_lo, v_hi) if axis == 0 else (u_lo, u_hi)
                # Ends on the block lattice, not the window's: its anti-aliased sides are
                # then the same whatever window draws them.
                a = math.floor(lo / PITCH_M) * PITCH_M
                b = math.ceil(hi / PITCH_M) * PITCH_M
                stretches = [(a, b, _ASPHALT_NEW)] if new else []
                if not new:  # stretches resurfaced or faded since the reference survey
                    cross = [
                        self.street(1 - axis, j)[0]
                        for j in range(int(a // PITCH_M) - 1, int(b // PITCH_M) + 2)
                    ]
                    stretches = street_stretches(self.seed, date, axis, k, cross)
                for a, b, col in stretches:
                    poly = box(pos - half, a, pos + half, b) if axis == 0 else box(
                        a, pos - half, b, pos + half)  # fmt: skip
                    cv.poly(self.to_world(poly), col)
                color = (60, 180, 210) if main else (220, 222, 224)
                width = 0.3 if new else 0.25
                dash = 3.0 if main else 6.0
                offsets = (-0.2, 0.2) if main else (0.0,)
                segs: list[tuple[Point, Point]] = []
                t = math.floor(lo / 9.0) * 9.0
                while t < hi:
                    for off in offsets:
                        seg = (
                            ((pos + off, t), (pos + off, t + dash))
                            if axis == 0
                            else ((t, pos + off), (t + dash, pos + off))
                        )
                        w = self.to_world(seg)
                        segs.append((w[0], w[1]))
                    t += 9.0
                if main:
                    for off in (-half + 1.0, half - 1.0):
                        line = (
                            ((pos + off, lo), (pos + off, hi))
                            if axis == 0
                            else ((lo, pos + off), (hi, pos + off))
                        )
                        w = self.to_world(line)
                        segs.append((w[0], w[1]))
                cv.segments(segs, color, width)


def _box_overlaps(
    b: tuple[float, float, float, float], u0: float, v0: float, u1: float, v1: float
) -> bool:
    return not (b[2] < u0 or b[0] > u1 or b[3] < v0 or b[1] > v1)


ALL_DATES = DATES
