"""The ``forest`` map: single tree crowns in stands, clearings, streams, lakes, tracks, farms.

Every tree is drawn (``crowns``): conifer and broadleaf stands of varying density and height,
each crown lit on its sunny side, casting its shadow onto its neighbours and the ground by
the date's sun; clearings (shrinking with the years), clear-cuts (felled at a later date,
``forest_cuts``, with the logging tracks built to them), streams and lakes are open ground.
Leaves turn with the season, each broadleaf its own autumn colour; conifers stay green.
Tracks, roads and farm buildings are vector drawings found from their world cell indices,
so any tile is drawn alone. The built-in surface (``objects``) is the same crowns' height
field. Pixels coarser than ``CROWN_MAX_GSD_M`` show each stand's mean look instead of its
crowns.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import Canvas, Color, DateLook, rect, shade
from air_sitl.maps.procedural.crowns import CELL_M, cell_window, crowns, stand_fields
from air_sitl.maps.procedural.forest_cuts import (
    TRACK_CELL_M,
    cut_mask,
    logging_tracks,
    track_node,
)
from air_sitl.maps.procedural.forest_years import meadow_look, stand_tone, tree_tone
from air_sitl.maps.procedural.noise import (
    FloatImage,
    fractal_noise,
    key_of,
    rng_for,
    unit2,
    value_noise,
    white_noise,
)
from air_sitl.maps.procedural.yeargap import ponds, renewed_noise, water_level

_CONIFER = {"summer": (52, 84, 50), "autumn": (74, 94, 38), "spring": (56, 86, 54)}
_DECIDUOUS = {"summer": (44, 104, 70), "autumn": (46, 104, 104), "spring": (70, 122, 110)}
_DECIDUOUS_ALT = {"summer": (56, 118, 86), "autumn": (40, 96, 146), "spring": (84, 132, 120)}
# Autumn broadleaves, each tree its own: still green, yellow, orange, brown (BGR).
_AUTUMN_LEAVES = ((52, 108, 66), (48, 150, 170), (38, 100, 168), (50, 82, 112))
# Leafless broadleaf crowns: grey-brown branches; green close to red, so that the spring
# survey's cool white balance and bluish haze leave them brown, not mauve.
_BARE: Color = (66, 98, 112)
_LITTER: Color = (46, 84, 106)  # last year's leaves on the forest floor
# Young growth on clear-cuts a few years old (BGR): green in summer, turning in autumn; in
# the April survey last year's dead grass among bare shrubs and saplings, straw-brown.
_REGROWTH = {"summer": (64, 120, 104), "autumn": (62, 116, 124), "spring": (74, 120, 150)}
_BOAT: Color = (214, 218, 222)  # white hulls
BOAT_CELL_M = 45.0  # one boat at most per cell of open water
BOAT_SHARE = 0.08  # share of the cells with a boat during a survey
_UNDERSTORY: Color = (30, 50, 36)
_MEADOW = {"summer": (70, 138, 112), "autumn": (84, 136, 150), "spring": (86, 124, 128)}
_SOIL: Color = (90, 112, 132)
_TRACK: Color = (110, 140, 160)
_NEW_TRACK: Color = (138, 156, 168)  # fresh gravel of a logging track built to a clear-cut
_ROAD: Color = (92, 92, 94)
_WATER: Color = (62, 58, 36)
_ROOFS: tuple[Color, ...] = ((60, 70, 150), (110, 110, 116), (70, 84, 112), (150, 160, 170))
ROAD_PITCH_M = 1700.0
FIRST_YEAR = 2009  # the first survey
CROWN_MAX_GSD_M = 10.0  # coarser pixels draw each stand's mean instead of its crowns
SHADOW_REACH_M = 12.0  # crowns this far toward the sun may shade a pixel
SHADOW_STEPS_M = (0.6, 1.2, 1.8, 2.5, 3.5, 4.8, 6.5, 9.0, 12.0)
STREAM_HALF = 0.012  # streams where a 520 m noise is within this of zero
# The April survey sees the year's high water (snowmelt, spring rain): streams run wider,
# over their open banks (at-a-station width ~ discharge^0.26, spring discharge ~3x summer's),
# and the wet hollows of the meadows hold water (``yeargap.ponds``' wetness, raised).
SPRING_STREAM_WIDTH = 1.3
SPRING_POND_FILL = 1.0
# Coarse levels (crowns below a pixel), measured on the crowns drawn at 0.6 m: crown cover per
# unit tree density, mean canopy height over the stand height, the mean radial position on a
# crown, mean shadow on crowns and in the gaps between them.
MEAN_COVER = 1.0
MEAN_HEIGHT = 0.95
MEAN_RADIAL = 0.67
MEAN_SHADOW_CROWN = 0.3
MEAN_SHADOW_GAP = 0.8


DRY_RADIUS_M = 2000.0  # no lake this close to home: flights start over land, not water


class ForestWorld:
    """The forest generator for one seed; ``home_en_m`` (UTM) keeps lakes away from home."""

    def __init__(self, seed: int, home_en_m: tuple[float, float] | None = None) -> None:
        self.seed = seed
        self.home_en_m = home_en_m

    def draw(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.uint8]:
        """One BGR tile of ``size`` pixels at absolute lattice (x0, y0)."""
        k = key_of(self.seed, 41)
        pm = 1.0 / gsd_m
        season = date.season
        pad = math.ceil(SHADOW_REACH_M * pm) if gsd_m <= CROWN_MAX_GSD_M else 0
        g = self._ground(x0 - pad, y0 - pad, size + 2 * pad, gsd_m, date)
        inner = (slice(pad, pad + size), slice(pad, pad + size))
        if pad:
            shadow = _cast_shadow(g.height_m, pad, size, gsd_m, date)
            g = _Ground(*(layer[inner] for layer in g))
        else:  # crowns below a pixel: the mean shadow of crowns and of the gaps between
            gaps = np.clip(1.0 - g.meadow - g.cut - g.water - g.cover, 0.0, 1.0)
            shadow = MEAN_SHADOW_CROWN * g.cover + MEAN_SHADOW_GAP * gaps
        fine = renewed_noise(k + 3, self.seed, date, x0, y0, size, 1.2 * pm, 2)
        # Crowns: species colour, per-tree tint, darker rims, the side toward the sun lit. Tops
        # bright whatever the sun (the sun-independent part keeps the dates aligned).
        dec = np.array(_DECIDUOUS[season], dtype=np.float32)
        dec_alt = np.array(_DECIDUOUS_ALT[season], dtype=np.float32)
        tint = g.tint[:, :, None]
        broadleaf = dec * (1.0 - tint) + dec_alt * tint
        if season == "autumn":
            broadleaf = _autumn_broadleaf(g.tint, bool(pad))
        con = np.array(_CONIFER[season], dtype=np.float32) * (0.9 + 0.2 * tint)
        cf = g.conifer[:, :, None]
        crown_col = con * cf + broadleaf * (1.0 - cf)
        if date.leaf_off:
            # Bare broadleaves: a veil of branches over the litter on the forest floor.
            twigs = np.clip(0.5 + 0.9 * fine, 0.0, 1.0)[:, :, None] * (1.0 - cf)
            floor = np.array(_LITTER, dtype=np.float32)
            bare = np.array(_BARE, dtype=np.float32)
            crown_col = crown_col * cf + (bare * twigs + floor * (1.0 - twigs)) * (1.0 - cf)
        lit_gain = np.float32(0.18 + 0.12 * _low_sun(date))
        shade_con = 1.0 + lit_gain * g.lit - 0.35 * g.radial
        shade_dec = 1.05 + 0.8 * lit_gain * g.lit - 0.35 * g.radial * g.radial + 0.08 * fine
        shading = (shade_con * g.conifer + shade_dec * (1.0 - g.conifer)) * (
            1.0 + 0.012 * (g.height_m - 18.0) * g.cover
        )
        if date.leaf_off:  # light passes through bare crowns: little shading of their own
            shading = shading * g.conifer + (0.75 + 0.25 * shading) * (1.0 - g.conifer)
        stands = stand_tone(self.seed, date, x0, y0, size, gsd_m)
        if date.leaf_off:  # bare broadleaf stands: their floor shows, not their canopy's tone
            stands = 1.0 + (stands - 1.0) * g.conifer
        gain = stands * tree_tone(date, g.tint) if pad else stands  # mean gain of trees: 1
        img = crown_col * (shading * g.cover * gain)[:, :, None]
        # Between crowns: dark understory in the forest, meadow in clearings, soil on cuts.
        # Meadows: the soil's patches stay, the grass on them (mown, grazed, dry) is the year's.
        season_key = key_of(self.seed, 43, date.index)
        meadow_tex = 1.0 + 0.04 * fractal_noise(k + 7, x0, y0, size, 6.0 * pm, 3) + 0.06 * fine
        meadow_tex += 0.07 * fractal_noise(season_key, x0, y0, size, 5.0 * pm, 3)
        under = np.array(_UNDERSTORY, dtype=np.float32) * (1.0 + 0.1 * fine)[:, :, None]
        meadow = meadow_look(self.seed, date, x0, y0, size, gsd_m, _MEADOW[season], meadow_tex)
        soil = np.array(_SOIL, dtype=np.float32) * (1.0 + 0.12 * fine)[:, :, None]
        young = np.clip((0.9 - g.cut) * 3.0, 0.0, 1.0) * (g.cut > 0.3)  # older cuts: regrowth
        growth = np.array(_REGROWTH[season], dtype=np.float32) * (1.0 + 0.25 * fine)[:, :, None]
        soil = soil * (1.0 - young[:, :, None]) + growth * young[:, :, None]
        if date.leaf_off:
            under = under * 0.4 + np.array(_LITTER, dtype=np.float32) * 0.6
        gap = under * (1.0 - g.meadow[:, :, None]) + meadow * g.meadow[:, :, None]
        gap = gap * (1.0 - g.cut[:, :, None]) + soil * g.cut[:, :, None]
        img += gap * (1.0 - g.cover)[:, :, None]
        # Tracks, roads and farms on top; then water; then the shadows of the crowns.
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        cv.img = np.clip(img, 0, 255).astype(np.uint8)
        self._tracks(cv, date.index)
        self._roads(cv, date)
        out: npt.NDArray[np.float32] = cv.img.astype(np.float32)
        if float(g.water.max()) > 0.0:
            ripple = 1.0 + 0.06 * value_noise(k + 10, x0, y0, size, 4.0 * pm)
            ripple += 0.06 * fractal_noise(k + 12, x0, y0, size, 1.5 * pm, 2)
            water = np.array(_WATER, dtype=np.float32)[None, None, :] * ripple[:, :, None]
            out = out * (1.0 - g.water[:, :, None]) + water * g.water[:, :, None]
            boats = self._boats(x0, y0, size, gsd_m, date, g.water)
            if boats is not None:  # moored or out on the lake: where they are that day
                hull = np.array(_BOAT, dtype=np.float32)[None, None, :]
                out = out * (1.0 - boats[:, :, None]) + hull * boats[:, :, None]
        if date.leaf_off:  # bare crowns cast thin shadows
            shadow = shadow * (0.45 + 0.55 * g.conifer)
        out *= (1.0 - (0.3 + 0.25 * (1.0 - g.cover)) * shadow)[:, :, None]
        # Canopy gaps and needles at 0.3-0.6 m, and each survey's own grain.
        out *= (1.0 + 0.12 * g.cover * white_noise(k + 13, x0, y0, size))[:, :, None]
        date_key = key_of(self.seed, 42, date.index)
        out += float(7.0 * min(1.0, 0.6 * pm)) * white_noise(date_key, x0, y0, size)[:, :, None]
        return np.clip(out, 0, 255).astype(np.uint8)

    def objects(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.float32]:
        """Canopy heights above the terrain (float32 m) of one tile, as :meth:`draw` shows it.

        The crowns the texture draws (cones and domes of 8-28 m trees); clearings, clear-cuts,
        lakes, streams, tracks, roads and farmyards are open ground (0 m). Where crowns are
        below a pixel, the stand's mean canopy height times its crown cover.
        """
        heights: npt.NDArray[np.float32] = self._ground(x0, y0, size, gsd_m, date).height_m
        return heights

    def _ground(self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook) -> _Ground:
        """What covers each pixel of a window: crowns, clearings, cuts, water, tracks."""
        k = key_of(self.seed, 41)
        d = date.index
        thr = 1.45 + 0.12 * d  # clearings shrink with the years: vegetation growth
        clear_px = _sample(fractal_noise, k + 6, x0, y0, size, gsd_m, 160.0, 3)
        meadow = np.clip((clear_px - thr + 0.08) * 6.0, 0.0, 1.0)
        stream_px = _sample(value_noise, k + 20, x0, y0, size, gsd_m, 520.0)
        stream_on = _sample(value_noise, k + 21, x0, y0, size, gsd_m, 1400.0) > -0.3
        half = STREAM_HALF * (SPRING_STREAM_WIDTH if date.leaf_off else 1.0)
        stream = np.clip((half - np.abs(stream_px)) * 80.0 * stream_on, 0.0, 1.0)
        # Lakes stand higher or lower each year than at the reference survey (a higher lake
        # drowns its shore's trees; the shore a lower one left is grass); ponds fill and dry
        # in the clearings.
        lake = self._lake(x0, y0, size, gsd_m, date)
        lake_ref = self._lake(x0, y0, size, gsd_m)
        meadow = np.maximum(meadow, lake_ref - lake)
        fill = SPRING_POND_FILL if date.leaf_off else 0.0
        pond = ponds(self.seed, date, x0, y0, size, gsd_m, fill) * meadow
        water: FloatImage = np.maximum(np.maximum(stream, lake), pond).astype(np.float32)
        felled = cut_mask(self.seed, x0, y0, size, gsd_m, d)
        cut = np.zeros((size, size), np.float32) if felled is None else felled
        # Tracks, roads and yards: whatever those drawings touch on a black canvas.
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        self._tracks(cv, d)
        self._roads(cv, date)
        drawn = (cv.img[:, :, 0] | cv.img[:, :, 1] | cv.img[:, :, 2]) > 0
        opened = np.maximum(drawn.astype(np.float32), np.maximum(water, lake_ref))
        opened = np.maximum(opened, cut)
        sun_e, sun_n = date.sun_dir()
        if gsd_m <= CROWN_MAX_GSD_M:
            i0, j0, n = cell_window(x0, y0, size, gsd_m)
            # Trees stand off clearings (a few scattered into them) and streams.
            clear_c = _sample(fractal_noise, k + 6, i0, j0, n, CELL_M, 160.0, 3)
            stream_c = _sample(value_noise, k + 20, i0, j0, n, CELL_M, 520.0)
            ii = np.arange(i0, i0 + n, dtype=np.int64)[None, :]
            jj = np.arange(j0, j0 + n, dtype=np.int64)[:, None]
            scatter = unit2(ii, jj, k + 22).astype(np.float32)
            keep = (clear_c - thr < 0.35 * scatter - 0.12) & (np.abs(stream_c) > 2 * STREAM_HALF)
            years = int(date.label[:4]) - FIRST_YEAR
            c = crowns(k + 30, x0, y0, size, gsd_m, (sun_e, -sun_n), keep, years)
            cover = c.cover * (1.0 - (opened > 0.5))
            return _Ground(
                c.height_m * cover, cover, c.lit, c.radial, c.conifer, c.tint, meadow, cut, water
            )
        # Crowns below a pixel: the stand's canopy as a whole.
        step = gsd_m / CELL_M
        c0x, c0y = (x0 + 0.5) * step - 0.5, (y0 + 0.5) * step - 0.5
        stand = stand_fields(k + 30, c0x, c0y, size, step)
        forest = np.clip(1.0 - np.clip((clear_px - thr + 0.12) * 5.0, 0.0, 1.0) - opened, 0, 1)
        cover = (forest * stand.density * MEAN_COVER).astype(np.float32)
        zero = np.zeros_like(cover)
        return _Ground(
            (stand.height_m * MEAN_HEIGHT * cover).astype(np.float32),
            cover,
            zero,
            zero + MEAN_RADIAL,
            stand.conifer,
            zero + 0.5,
            meadow,
            cut,
            water,
        )

    def _lake(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook | None = None
    ) -> FloatImage:
        """1 on lakes at this survey's water level (``date`` None: the reference survey's);
        0 within DRY_RADIUS_M of home."""
        k = key_of(self.seed, 41)
        lake_n = value_noise(k + 8, x0, y0, size, 700.0 / gsd_m) + 0.25 * value_noise(
            k + 9, x0, y0, size, 150.0 / gsd_m
        )
        level: FloatImage | float = 0.0
        if date is not None:
            level = water_level(self.seed, date, x0, y0, size, gsd_m)
        lake: FloatImage = np.clip((-lake_n - 1.7 + level) * 30.0, 0.0, 1.0)
        if self.home_en_m is not None and float(lake.max()) > 0.0:
            lake *= self._dry_near_home(x0, y0, size, gsd_m)
        return lake

    def _boats(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook, water: FloatImage
    ) -> FloatImage | None:
        """Mask of the boats on lakes during this survey (whether a boat is there is decided at
        its centre, whatever window draws it)."""
        if gsd_m > 2.0 or float(water.max()) < 0.5:
            return None
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        for i in range(math.floor(cv.e_min / BOAT_CELL_M), math.floor(cv.e_max / BOAT_CELL_M) + 1):
            for j in range(
                math.floor(cv.n_min / BOAT_CELL_M), math.floor(cv.n_max / BOAT_CELL_M) + 1
            ):
                rng = rng_for(self.seed, 81, date.index, i, j)
                if rng.random() > BOAT_SHARE:
                    continue
                e = (i + rng.uniform(0.1, 0.9)) * BOAT_CELL_M
                n = (j + rng.uniform(0.1, 0.9)) * BOAT_CELL_M
                if not cv.overlaps(e, n, e, n, 5.0):
                    continue
                col, row = math.floor(e / gsd_m), math.floor(-n / gsd_m)
                if float(self._lake(col, row, 1, gsd_m, date)[0, 0]) < 0.99:
                    continue
                a = rng.uniform(0.0, math.pi)
                length = rng.uniform(3.0, 8.0)
                hull = rect(e, n, length / 2, length * 0.18, math.cos(a), math.sin(a))
                cv.poly(hull, (255,), "shadow")
        if not cv.shadow.any():
            return None
        return cv.shadow.astype(np.float32) * np.float32(1.0 / 255.0)

    def _dry_near_home(self, x0: int, y0: int, size: int, gsd_m: float) -> npt.NDArray[np.float32]:
        """0 within DRY_RADIUS_M of home, rising to 1 over the next 500 m."""
        assert self.home_en_m is not None
        he, hn = self.home_en_m
        e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m - he
        n = -(y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m - hn
        dist = np.hypot(e[None, :], n[:, None])
        return np.clip((dist - DRY_RADIUS_M) / 500.0, 0.0, 1.0).astype(np.float32)

    def _tracks(self, cv: Canvas, d: int) -> None:
        """Dirt tracks joining jittered nodes of a coarse grid (some links missing)."""
        i0 = math.floor(cv.e_min / TRACK_CELL_M) - 1
        i1 = math.floor(cv.e_max / TRACK_CELL_M) + 1
        j0 = math.floor(cv.n_min / TRACK_CELL_M) - 1
        j1 = math.floor(cv.n_max / TRACK_CELL_M) + 1
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                a = track_node(self.seed, i, j)
                rng = rng_for(self.seed, 62, i, j)
                links = (rng.random() < 0.55, rng.random() < 0.45)
                wig = rng.uniform(-40, 40, size=2)
                for (di, dj), on, w in zip(((1, 0), (0, 1)), links, wig, strict=True):
                    if not on:
                        continue
                    b = track_node(self.seed, i + di, j + dj)
                    if not cv.overlaps(
                        min(a[0], b[0]), min(a[1], b[1]), max(a[0], b[0]), max(a[1], b[1]), 50.0
                    ):
                        continue
                    pts = []
                    for t in np.linspace(0.0, 1.0, 17):
                        bend = math.sin(math.pi * t) * w
                        pts.append(
                            (
                                a[0] + (b[0] - a[0]) * t - dj * bend,
                                a[1] + (b[1] - a[1]) * t + di * bend,
                            )
                        )
                    cv.line(pts, shade(_TRACK, 0.85), 4.2)
                    cv.line(pts, _TRACK, 3.0)
        for pts in logging_tracks(self.seed, cv.e_min, cv.n_min, cv.e_max, cv.n_max, d):
            cv.line(pts, shade(_NEW_TRACK, 0.85), 4.5)
            cv.line(pts, _NEW_TRACK, 3.4)

    def _roads(self, cv: Canvas, date: DateLook) -> None:
        """Paved roads on a coarse grid, with farmsteads (roofs and shadows) beside them."""
        d = date.index
        for axis in (0, 1):
            lo, hi = (cv.e_min, cv.e_max) if axis == 0 else (cv.n_min, cv.n_max)
            along_lo, along_hi = (cv.n_min, cv.n_max) if axis == 0 else (cv.e_min, cv.e_max)
            for kk in range(
                math.floor((lo - 200) / ROAD_PITCH_M), math.floor((hi + 200) / ROAD_PITCH_M) + 1
            ):
                rng = rng_for(self.seed, 71, axis, kk)
                base = kk * ROAD_PITCH_M + rng.uniform(-300, 300)
                phase, amp = rng.uniform(0, 6.28), rng.uniform(20, 80)

                def pos(
                    t: float, base: float = base, phase: float = phase, amp: float = amp
                ) -> float:
                    return base + amp * math.sin(t / 450.0 + phase)

                ts = np.arange(math.floor(along_lo / 20.0) * 20.0 - 60.0, along_hi + 80.0, 20.0)
                pts = [(pos(t), t) if axis == 0 else (t, pos(t)) for t in ts]
                if axis == 0 and (
                    min(p[0] for p in pts) > hi + 60 or max(p[0] for p in pts) < lo - 60
                ):
                    continue
                if axis == 1 and (
                    min(p[1] for p in pts) > hi + 60 or max(p[1] for p in pts) < lo - 60
                ):
                    continue
                cv.line(pts, (120, 128, 132), 9.0)
                cv.line(pts, _ROAD if d < 2 or kk % 2 else shade(_ROAD, 0.6), 7.0)
                for s in range(math.floor(along_lo / 200.0) - 1, math.floor(along_hi / 200.0) + 2):
                    frng = rng_for(self.seed, 72, axis, kk, s)
                    if frng.random() > 0.22:
                        continue
                    t = (s + 0.5) * 200.0
                    side = 1.0 if frng.random() < 0.5 else -1.0
                    off = side * frng.uniform(22.0, 40.0)
                    c = (pos(t) + off, t) if axis == 0 else (t, pos(t) + off)
                    yard = rect(c[0], c[1], frng.uniform(18, 30), frng.uniform(18, 30), 1.0, 0.0)
                    cv.poly(yard, shade(_MEADOW[date.season], 1.1))
                    cv.line([c, (pos(t), t) if axis == 0 else (t, pos(t))], _TRACK, 3.0)
                    for _ in range(int(frng.integers(2, 5))):
                        bc = (c[0] + frng.uniform(-14, 14), c[1] + frng.uniform(-14, 14))
                        hw, hh = frng.uniform(4, 10), frng.uniform(3.5, 7)
                        roof = _ROOFS[int(frng.integers(len(_ROOFS)))]
                        born = 1 if frng.random() < 0.2 else 0
                        if born > d:
                            continue
                        poly = rect(bc[0], bc[1], hw, hh, 1.0, 0.0)
                        dx, dy = date.shadow_vector(frng.uniform(4, 8))
                        shadow = [(p[0] + dx, p[1] + dy) for p in poly]
                        hull = cv2.convexHull(np.asarray(poly + shadow, dtype=np.float32))
                        cv.poly([(float(p[0][0]), float(p[0][1])) for p in hull], (40, 52, 50))
                        cv.poly(poly, shade(roof, 0.85))
                        cv.poly(
                            [
                                *rect(bc[0], bc[1], hw, hh / 2, 1.0, 0.0)[:2],
                                (bc[0] + hw, bc[1]),
                                (bc[0] - hw, bc[1]),
                            ],
                            roof,
                        )


class _Ground(NamedTuple):
    """Layers of one window (all size x size float32)."""

    height_m: FloatImage  # canopy surface above the ground
    cover: FloatImage  # crown cover (1 on a crown; on coarse levels the stand's mean)
    lit: FloatImage
    radial: FloatImage
    conifer: FloatImage
    tint: FloatImage
    meadow: FloatImage  # 1 in clearings (meadow between the trees)
    cut: FloatImage  # 1 on clear-cuts
    water: FloatImage  # 1 on lakes and streams


def _sample(  # type: ignore[no-untyped-def]
    noise, key: int, x0: int, y0: int, n: int, step_m: float, feature_m: float, *octaves: int
) -> FloatImage:
    """A noise field of the world in metres at the centres of n x n squares of ``step_m``
    from square (x0, y0): pixels (step = gsd) or tree cells (step = CELL_M)."""
    result: FloatImage = noise(key, x0 + 0.5, y0 + 0.5, n, feature_m / step_m, *octaves)
    return result


def _autumn_broadleaf(tint: FloatImage, crowns_drawn: bool) -> npt.NDArray[np.float32]:
    """Autumn colours of broadleaf crowns: each tree (its tint) still green, yellow, orange or
    brown; where crowns are below a pixel, their mean."""
    leaves = np.array(_AUTUMN_LEAVES, dtype=np.float32)
    if not crowns_drawn:
        return np.broadcast_to(leaves.mean(axis=0), (*tint.shape, 3)).astype(np.float32)
    # The tint's fractional digits pick the colour, the tint itself still shades the crown.
    which = np.minimum((np.mod(tint * 7.0, 1.0) * len(leaves)).astype(np.int64), len(leaves) - 1)
    tinted: npt.NDArray[np.float32] = leaves[which] * (0.9 + 0.2 * tint)[:, :, None]
    return tinted


def _low_sun(date: DateLook) -> float:
    """0 with the sun high, toward 1 with it low (longer shadows, harder light)."""
    return float(np.clip((60.0 - date.sun_elevation_deg) / 30.0, 0.0, 1.0))


def _cast_shadow(
    height: FloatImage,
    pad: int,
    size: int,
    gsd_m: float,
    date: DateLook,
    steps_m: tuple[float, ...] = SHADOW_STEPS_M,
) -> FloatImage:
    """Shadow (0..1) on the inner size x size pixels of a height field padded by ``pad``:
    whether the crowns toward the sun rise above the sun's ray through the pixel."""
    sun_e, sun_n = date.sun_dir()
    rise = math.tan(math.radians(date.sun_elevation_deg))
    here = height[pad : pad + size, pad : pad + size]
    worst = np.zeros((size, size), dtype=np.float32)
    seen: set[tuple[int, int]] = set()
    for t in steps_m:
        dx, dy = round(t * sun_e / gsd_m), round(-t * sun_n / gsd_m)
        if (dx, dy) in seen or max(abs(dx), abs(dy)) > pad or (dx, dy) == (0, 0):
            continue
        seen.add((dx, dy))
        toward = height[pad + dy : pad + dy + size, pad + dx : pad + dx + size]
        worst = np.maximum(worst, toward - np.float32(math.hypot(dx, dy) * gsd_m * rise) - here)
    shadow: FloatImage = np.clip(worst * np.float32(0.7), 0.0, 1.0)
    return shadow
