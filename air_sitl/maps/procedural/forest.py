"""The ``forest`` map: shaded canopy at several scales, clearings, lakes, tracks, roads, farms.

The canopy is a height field made of noise at crown (3 m), group (8 m) and stand (80 m)
scales, lit by the date's sun: what a real canopy looks like from above, and cheap (a few
small matrix products per tile). Tracks, roads and farm buildings are vector drawings found
from their world cell indices, so any tile is drawn alone.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import Canvas, Color, DateLook, Point, rect, shade
from air_sitl.maps.procedural.noise import (
    FloatImage,
    fractal_noise,
    key_of,
    rng_for,
    value_noise,
    white_noise,
)

_CONIFER = {"summer": (38, 64, 40), "autumn": (36, 60, 40), "spring": (44, 66, 46)}
_DECIDUOUS = {"summer": (44, 100, 66), "autumn": (46, 96, 140), "spring": (72, 104, 104)}
_MEADOW = {"summer": (70, 138, 112), "autumn": (84, 136, 150), "spring": (86, 124, 128)}
_SOIL: Color = (90, 112, 132)
_TRACK: Color = (110, 140, 160)
_ROAD: Color = (92, 92, 94)
_WATER: Color = (62, 58, 36)
_ROOFS: tuple[Color, ...] = ((60, 70, 150), (110, 110, 116), (70, 84, 112), (150, 160, 170))
TRACK_CELL_M = 380.0
ROAD_PITCH_M = 1700.0
CUT_CELL_M = 170.0


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
        d = date.index
        season = date.season
        # Canopy height field (arbitrary units) and its sun shading.
        height, crowns, _, fine, w_crown, _ = _canopy(k, x0, y0, size, pm)
        gx = cv2.Sobel(height, cv2.CV_32F, 1, 0, ksize=3) * np.float32(pm / 8.0 * 3.0)
        gy = cv2.Sobel(height, cv2.CV_32F, 0, 1, ksize=3) * np.float32(pm / 8.0 * 3.0)
        sun_e, sun_n = date.sun_dir()
        # Image x is east, image y is south: slope toward the sun lights the crown.
        lit = gx * np.float32(sun_e) - gy * np.float32(sun_n)
        low_sun = 1.0 / math.tan(math.radians(date.sun_elevation_deg))
        # Crown tops are bright whatever the sun (sun-independent structure keeps dates
        # aligned), their sunny side brighter still.
        tops = np.clip(height, -1.5, 1.5) * np.float32(0.28)
        shading = 1.0 + tops + np.clip(lit * np.float32(0.04 * low_sun), -0.08, 0.08)
        gaps = np.clip((-height - 0.7) * 1.5, 0.0, 1.0)  # deep gaps are in shadow
        shading *= 1.0 - 0.45 * gaps
        # Species mix per stand.
        stand = fractal_noise(k + 4, x0, y0, size, 90.0 * pm, 2)
        conifer = np.clip(0.5 + stand * 0.9, 0.0, 1.0)
        dec_col = np.array(_DECIDUOUS[season], dtype=np.float32)
        if season == "autumn":
            mix = np.clip(0.5 + 0.8 * value_noise(k + 5, x0, y0, size, 6.0 * pm), 0.0, 1.0)
            alt = np.array((44, 118, 150), dtype=np.float32)
            dec = (
                dec_col[None, None, :] * (1 - mix[:, :, None])
                + alt[None, None, :] * mix[:, :, None]
            )
        else:
            dec = np.broadcast_to(dec_col, (size, size, 3))
        con_col = np.array(_CONIFER[season], dtype=np.float32)
        canopy = con_col[None, None, :] * conifer[:, :, None] + dec * (1.0 - conifer[:, :, None])
        # Crown shadows darken a canopy seen from afar; keep that when crowns are faded out.
        canopy = canopy * (shading * np.float32(1.0 - 0.08 * (1.0 - w_crown)))[:, :, None]
        # Clearings (shrinking with the years: vegetation growth) and meadows.
        clear_n = fractal_noise(k + 6, x0, y0, size, 160.0 * pm, 3)
        thr = 1.45 + 0.12 * d
        open_a = np.clip((clear_n - thr) * 5.0, 0.0, 1.0)
        meadow_tex = 1.0 + 0.07 * fractal_noise(k + 7, x0, y0, size, 6.0 * pm, 3)
        meadow_tex += 0.06 * fine
        shrubs = np.clip((crowns - 1.7) * 2.0, 0.0, 0.4)  # scattered bushes in meadows
        meadow_tex *= 1.0 - shrubs
        meadow = np.array(_MEADOW[season], dtype=np.float32)[None, None, :] * meadow_tex[:, :, None]
        # Scattered single trees at clearing edges keep texture there.
        edge_trees = np.clip((height - 0.35) * 3.0, 0.0, 1.0) * np.clip(
            1.6 - (clear_n - thr) * 4, 0.0, 1.0
        )
        open_a = open_a * (1.0 - edge_trees)
        # Clear-cuts: whole cells felled at a given date (construction change of a forest).
        cut = self._cuts(x0, y0, size, gsd_m, d)
        soil = np.array(_SOIL, dtype=np.float32)[None, None, :] * (1.0 + 0.12 * fine[:, :, None])
        img = canopy * (1.0 - open_a[:, :, None]) + meadow * open_a[:, :, None]
        if cut is not None:
            img = img * (1.0 - cut[:, :, None]) + soil * cut[:, :, None]
        # Lakes where a very smooth noise is low; a darker rim.
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        cv.img = np.clip(img, 0, 255).astype(np.uint8)
        self._tracks(cv, d)
        self._roads(cv, date)
        out: npt.NDArray[np.float32] = cv.img.astype(np.float32)
        water_n = value_noise(k + 8, x0, y0, size, 700.0 * pm) + 0.25 * value_noise(
            k + 9, x0, y0, size, 150.0 * pm
        )
        water_a = np.clip((-water_n - 1.7) * 8.0, 0.0, 1.0)
        if self.home_en_m is not None and float(water_a.max()) > 0.0:
            water_a *= self._dry_near_home(x0, y0, size, gsd_m)
        if float(water_a.max()) > 0.0:
            # Lakes last: tracks and roads end at the shore.
            ripple = 1.0 + 0.06 * value_noise(k + 10, x0, y0, size, 4.0 * pm)
            ripple += 0.06 * fractal_noise(k + 12, x0, y0, size, 1.5 * pm, 2)
            water = np.array(_WATER, dtype=np.float32)[None, None, :] * ripple[:, :, None]
            out = (out * (1.0 - water_a[:, :, None]) + water * water_a[:, :, None]).astype(
                np.float32
            )
        out += float(5.0 * min(1.0, 0.6 * pm)) * white_noise(k + 11, x0, y0, size)[:, :, None]
        return np.clip(out, 0, 255).astype(np.uint8)

    def objects(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.float32]:
        """Canopy heights above the terrain (float32 m) of one tile, as :meth:`draw` shows it.

        The crown height field that shades the texture sets the canopy (bright tops high,
        dark gaps low, about 12-24 m); clearings, clear-cuts, lakes, tracks, roads and farmyards
        are open ground (0 m).
        """
        k = key_of(self.seed, 41)
        pm = 1.0 / gsd_m
        d = date.index
        height, crowns, groups, _, w_crown, w_group = _canopy(k, x0, y0, size, pm)
        clear_n = fractal_noise(k + 6, x0, y0, size, 160.0 * pm, 3)
        thr = 1.45 + 0.12 * d
        open_a = np.clip((clear_n - thr) * 5.0, 0.0, 1.0)
        edge_trees = np.clip((height - 0.35) * 3.0, 0.0, 1.0) * np.clip(
            1.6 - (clear_n - thr) * 4, 0.0, 1.0
        )
        open_a = open_a * (1.0 - edge_trees)
        stand = fractal_noise(k + 4, x0, y0, size, 90.0 * pm, 2)
        # Tree groups shape the canopy; single crowns (3 m) only by a metre: the texture's
        # shading carries them, a rougher height field would cost every frame dearly.
        canopy = (17.0 + 3.0 * stand + 2.5 * w_group * groups + 1.0 * w_crown * crowns).astype(
            np.float32
        )
        cover = 1.0 - open_a
        cut = self._cuts(x0, y0, size, gsd_m, d)
        if cut is not None:
            cover *= 1.0 - cut
        water_n = value_noise(k + 8, x0, y0, size, 700.0 * pm) + 0.25 * value_noise(
            k + 9, x0, y0, size, 150.0 * pm
        )
        water_a = np.clip((-water_n - 1.7) * 8.0, 0.0, 1.0)
        if self.home_en_m is not None and float(water_a.max()) > 0.0:
            water_a *= self._dry_near_home(x0, y0, size, gsd_m)
        cover *= 1.0 - water_a
        # Tracks, roads and yards: whatever those drawings touch on a black canvas.
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        self._tracks(cv, d)
        self._roads(cv, date)
        opened = cv.img.max(axis=2) > 0
        cover[opened] = 0.0
        # A crown edge is steep: the canopy keeps its height until the cover is mostly gone.
        cover = np.clip((cover - 0.2) * 2.0, 0.0, 1.0)
        heights: npt.NDArray[np.float32] = (canopy * cover).astype(np.float32)
        return heights

    def _dry_near_home(self, x0: int, y0: int, size: int, gsd_m: float) -> npt.NDArray[np.float32]:
        """0 within DRY_RADIUS_M of home, rising to 1 over the next 500 m."""
        assert self.home_en_m is not None
        he, hn = self.home_en_m
        e = (x0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m - he
        n = -(y0 + np.arange(size, dtype=np.float64) + 0.5) * gsd_m - hn
        dist = np.hypot(e[None, :], n[:, None])
        return np.clip((dist - DRY_RADIUS_M) / 500.0, 0.0, 1.0).astype(np.float32)

    def _cuts(
        self, x0: int, y0: int, size: int, gsd_m: float, d: int
    ) -> npt.NDArray[np.float32] | None:
        """Mask of cells clear-cut at or before date ``d``."""
        if d == 0:
            return None
        e0, e1 = x0 * gsd_m, (x0 + size) * gsd_m
        n0, n1 = -(y0 + size) * gsd_m, -y0 * gsd_m
        mask = np.zeros((size, size), dtype=np.uint8)
        cv = Canvas(x0, y0, size, gsd_m, (0, 0, 0))
        cv.shadow = mask
        for i in range(math.floor(e0 / CUT_CELL_M), math.floor(e1 / CUT_CELL_M) + 1):
            for j in range(math.floor(n0 / CUT_CELL_M), math.floor(n1 / CUT_CELL_M) + 1):
                rng = rng_for(self.seed, 51, i, j)
                u = rng.random()
                at = 1 if u < 0.05 else 2 if u < 0.10 else 9
                if at > d:
                    continue
                w, h = rng.uniform(40, 80), rng.uniform(30, 70)
                cx = (i + 0.5) * CUT_CELL_M + rng.uniform(-30, 30)
                cy = (j + 0.5) * CUT_CELL_M + rng.uniform(-30, 30)
                a = rng.uniform(0, math.pi)
                cv.poly(rect(cx, cy, w, h, math.cos(a), math.sin(a)), (255,), "shadow")
        if not mask.any():
            return None
        return mask.astype(np.float32) * np.float32(1.0 / 255.0)

    def _node(self, i: int, j: int) -> Point:
        rng = rng_for(self.seed, 61, i, j)
        return (
            (i + rng.uniform(0.2, 0.8)) * TRACK_CELL_M,
            (j + rng.uniform(0.2, 0.8)) * TRACK_CELL_M,
        )

    def _tracks(self, cv: Canvas, d: int) -> None:
        """Dirt tracks joining jittered nodes of a coarse grid (some links missing)."""
        i0 = math.floor(cv.e_min / TRACK_CELL_M) - 1
        i1 = math.floor(cv.e_max / TRACK_CELL_M) + 1
        j0 = math.floor(cv.n_min / TRACK_CELL_M) - 1
        j1 = math.floor(cv.n_max / TRACK_CELL_M) + 1
        for i in range(i0, i1 + 1):
            for j in range(j0, j1 + 1):
                a = self._node(i, j)
                rng = rng_for(self.seed, 62, i, j)
                links = (rng.random() < 0.55, rng.random() < 0.45)
                wig = rng.uniform(-40, 40, size=2)
                for (di, dj), on, w in zip(((1, 0), (0, 1)), links, wig, strict=True):
                    if not on:
                        continue
                    b = self._node(i + di, j + dj)
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


class _Canopy(NamedTuple):
    """A tile's canopy height field (arbitrary units) and what it is made of."""

    height: FloatImage
    crowns: FloatImage
    groups: FloatImage  # groups of trees
    fine: FloatImage
    w_crown: float  # weights: drawn coarse, features under ~2 px average out and fade
    w_group: float


def _canopy(k: int, x0: int, y0: int, size: int, pm: float) -> _Canopy:
    crowns = value_noise(k + 1, x0, y0, size, 3.0 * pm)
    groups = value_noise(k + 2, x0, y0, size, 8.0 * pm)
    fine = fractal_noise(k + 3, x0, y0, size, 1.2 * pm, 2)
    w_crown = float(np.clip((3.0 * pm - 1.0) / 2.0, 0.0, 1.0))
    w_group = float(np.clip((8.0 * pm - 1.0) / 2.0, 0.0, 1.0))
    height = 0.55 * w_crown * crowns + 0.35 * w_group * groups + 0.18 * fine
    return _Canopy(height, crowns, groups, fine, w_crown, w_group)
