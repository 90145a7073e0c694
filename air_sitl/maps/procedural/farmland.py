"""The ``farmland`` map: Midwest farmland on a survey grid, as NAIP shows Iowa and Nebraska.

Quarter sections of the one-mile survey grid (``farmland_layout``), split into fields whose
crops rotate year by year (corn, soybeans, wheat, alfalfa, grass), centre-pivot circles,
gravel section roads and a paved highway, a creek with its trees, prairie potholes and
wetlands whose water follows each year's wetness, farmsteads with shelterbelts and small towns
(``farmland_built``). A survey shows each field as its year's crop looks in the survey's
season: June rows of young corn and soybeans over dark soil, October stubble, standing dry
corn or fall tillage, April residue of last year's crop, tillage and green winter wheat; rows
run across the field in a direction chosen each year, along the headlands at its edges.

Every pixel is a function of its absolute position, the seed and the date (no polygon is
clipped to a window), so any window gives the same bytes for the same pixel. The built-in
surface (``objects``) raises the same trees, buildings, bins and standing crops.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import DATES, DateLook
from air_sitl.maps.procedural.farmland_built import (
    ASPHALT_BGR,
    FALLOW,
    GRAVEL,
    GRAVEL_BGR,
    PAVED,
    TREES,
    WATER,
    WETLAND,
    Layers,
    farmsteads,
    towns,
)
from air_sitl.maps.procedural.farmland_layout import (
    ALFALFA,
    CORN,
    GRASS,
    HIGHWAY_HALF_M,
    QUARTER_M,
    SOY,
    WHEAT,
    Fields,
    Grid,
    band,
    basin_wetness,
    creek_distance_m,
    crop_in,
    drainage,
    field_unit,
    fields,
    grid,
    hills,
    is_highway,
    pothole,
    roads,
    water_level,
    wetness,
    year_of,
)
from air_sitl.maps.procedural.forest import _cast_shadow
from air_sitl.maps.procedural.noise import (
    FloatImage,
    fractal_noise,
    key_of,
    unit2,
    value_noise,
    white_noise,
)
from air_sitl.maps.procedural.yeargap import changed_share, years_since_reference

# What a field looks like: (plant colour BGR, share of the ground the plants cover, row
# stripe amplitude, soil darkness (1 dry light .. 1.6 fresh tillage), height m, code).
_STATES: dict[str, tuple[tuple[float, float, float], float, float, float, float, int]] = {
    "corn_june": ((36, 108, 56), 0.6, 0.22, 1.15, 0.9, CORN),
    "soy_june": ((50, 120, 72), 0.25, 0.16, 1.1, 0.3, SOY),
    "wheat_ripe": ((92, 168, 192), 0.95, 0.05, 1.0, 0.8, WHEAT),
    "alfalfa": ((56, 134, 78), 0.95, 0.04, 1.0, 0.5, ALFALFA),
    "alfalfa_cut": ((96, 150, 140), 0.7, 0.25, 1.0, 0.1, ALFALFA),
    "grass": ((72, 128, 102), 0.92, 0.0, 1.0, 0.3, GRASS),
    "grass_dry": ((92, 138, 146), 0.9, 0.0, 1.0, 0.3, GRASS),
    "grass_spring": ((84, 136, 128), 0.85, 0.0, 1.0, 0.1, GRASS),
    "corn_dry": ((96, 142, 168), 0.9, 0.08, 1.0, 2.4, CORN),
    "corn_residue": ((132, 168, 188), 0.75, 0.2, 1.0, 0.2, CORN),
    "soy_dry": ((78, 132, 162), 0.85, 0.06, 1.0, 0.7, SOY),
    "soy_residue": ((150, 176, 194), 0.55, 0.1, 1.0, 0.05, SOY),
    "wheat_stubble": ((126, 170, 192), 0.7, 0.15, 1.0, 0.15, WHEAT),
    "wheat_green": ((70, 150, 100), 0.8, 0.12, 1.1, 0.2, WHEAT),
    "tilled": ((0, 0, 0), 0.0, 0.3, 1.6, 0.0, FALLOW),
    "planted": ((0, 0, 0), 0.0, 0.35, 1.4, 0.0, FALLOW),
    "fallow": ((86, 128, 124), 0.45, 0.05, 1.0, 0.2, FALLOW),
    # July-August (NAIP's season): canopies closed over the rows, small grain harvested.
    "corn_tall": ((40, 98, 52), 0.97, 0.03, 1.0, 2.5, CORN),
    "soy_full": ((58, 134, 82), 0.9, 0.07, 1.0, 0.8, SOY),
}
_STATE_NAMES = tuple(_STATES)
_SOIL_LIGHT = np.array((118, 136, 150), np.float32)  # eroded hilltops, dry (BGR)
_SOIL_DARK = np.array((54, 64, 76), np.float32)  # black loam
_WATER = np.array((70, 62, 42), np.float32)
_MUD = np.array((100, 118, 128), np.float32)
_CATTAIL = {"summer": (46, 96, 64), "autumn": (80, 118, 134), "spring": (84, 108, 118)}
_DITCH = {"summer": (72, 132, 104), "autumn": (92, 138, 142), "spring": (92, 134, 130)}
_LEAVES = {"summer": (44, 86, 50), "autumn": (52, 110, 130), "spring": (88, 98, 108)}
_CONIFER = (46, 74, 50)
_ROW_PERIOD_M = 4.6  # one planter pass of six 30-inch rows: what a 0.6 m pixel resolves
_HEADLAND_M = 12.0
SHADOW_REACH_M = 22.0
SHADOW_STEPS_M = (0.6, 1.2, 1.8, 2.5, 3.5, 4.8, 6.5, 9.0, 12.0, 16.0, 22.0)
CANOPY_MAX_GSD_M = 3.0  # coarser: trees as their stand's mean
PIVOT_RING_M = 54.0  # spacing of a pivot's towers: its wheel tracks
FIELD_EVERY_YEARS = 4.0  # mean years between changes of how a field is farmed (yeargap)
FIELD_TONE = 0.35  # largest relative brightness change of a field farmed otherwise
FIELD_YEAR_TONE = 0.16  # each field's own brightness a year (+-8 %: stand, variety, sowing)
# What stays inside a field from year to year (docs/map-dates.md, "What persists inside
# fields"): the soil's zones (eroded light knobs, dark wet swales) show in bare soil and
# through the crop, whose vigour follows them with the year's sign; grassed waterways; the
# row direction most farmers keep (the reference year's); headlands, pivot wheel tracks.
SWALE_SOIL = 0.3  # soil value (0 dark loam .. 1 light) a swale's middle loses
SWALE_CROP = 0.18  # a canopy's relative brightness in a swale's middle: darker (greener)
# in a dry year, paler (drowned out, thin) in a wet one: - SWALE_CROP * (0.5 - wet) / 0.35
KNOB_CROP = 0.3  # thinner crop on light (eroded) soil: cover * (1 - KNOB_CROP * (v - 0.5))
ROWS_KEPT = 0.8  # share of the fields planted in the reference year's direction every year
REFERENCE_YEAR = year_of(DATES[0].label)
# A waterway's grass, drawn per field and year: lush, mown for hay, dark, straw (dry year).
_WATERWAY = np.array(((72, 128, 102), (100, 150, 140), (58, 112, 78), (96, 140, 150)), np.float32)


class FarmlandWorld:
    """The farmland generator for one seed."""

    def __init__(self, seed: int) -> None:
        self.seed = seed

    def draw(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.uint8]:
        """One BGR tile of ``size`` pixels at absolute lattice (x0, y0)."""
        pad = math.ceil(SHADOW_REACH_M / gsd_m) if gsd_m <= CANOPY_MAX_GSD_M else 1
        lay = self._scene(x0 - pad, y0 - pad, size + 2 * pad, gsd_m, date)
        inner = (slice(pad, pad + size), slice(pad, pad + size))
        out = lay.col[inner]
        if gsd_m <= CANOPY_MAX_GSD_M:
            shadow = _cast_shadow(lay.height, pad, size, gsd_m, date, SHADOW_STEPS_M)
        else:  # crowns below a pixel: their mean shadow
            shadow = 0.35 * np.clip(lay.trees[inner], 0.0, 1.0)
        out = out * (1.0 - 0.55 * shadow)[:, :, None]
        pm = 1.0 / gsd_m
        grain = white_noise(key_of(self.seed, 0xF01, date.index), x0, y0, size)
        out = out + (np.float32(6.0 * min(1.0, 0.6 * pm)) * grain)[:, :, None]
        return np.clip(out, 0, 255).astype(np.uint8)

    def objects(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.float32]:
        """Heights above the terrain (float32 m): trees, buildings, bins, standing crops."""
        lay = self._scene(x0 - 1, y0 - 1, size + 2, gsd_m, date)
        heights: npt.NDArray[np.float32] = np.ascontiguousarray(lay.height[1:-1, 1:-1])
        return heights

    def land_cover(
        self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
    ) -> npt.NDArray[np.uint8]:
        """The land-cover code of each pixel in the survey's year (``farmland_built``'s
        codes: crops 0..4, then trees, water, wetland, roads, buildings ...)."""
        lay = self._scene(x0 - 1, y0 - 1, size + 2, gsd_m, date)
        return np.ascontiguousarray(lay.code[1:-1, 1:-1])

    def _scene(self, x0: int, y0: int, size: int, gsd_m: float, date: DateLook) -> Layers:
        """Colours before shadows, heights and codes over a window."""
        seed = self.seed
        year = year_of(date.label)
        season = date.season
        stage = _stage(date)
        lay = Layers(x0, y0, size, gsd_m)
        g = grid(seed, x0, y0, size, gsd_m)
        f = fields(seed, g, year, gsd_m)
        crop = np.where(f.pasture, GRASS, crop_in(seed, f.key, year)[f.fid])
        prev = np.where(f.pasture, GRASS, crop_in(seed, f.key, year - 1)[f.fid])
        running = f.running
        state = _field_state(seed, f.key, f.fid, crop, prev, year, stage, wetness(seed, year))
        idle = (f.pivot > 0.5) & ~running & (crop != GRASS)
        state = np.where(idle, _STATE_NAMES.index("fallow"), state)
        # Soil: light on the eroded hilltops, darker in swales and in a wet year.
        k = key_of(seed, 0xF10)
        wet = wetness(seed, year)
        soil_v = 0.45 + 0.15 * hills(seed, x0, y0, size, gsd_m)
        soil_v += 0.1 * value_noise(k, x0 + 0.5, y0 + 0.5, size, 90.0 / gsd_m)
        soil_v += 0.1 * value_noise(k + 3, x0 + 0.5, y0 + 0.5, size, 320.0 / gsd_m)
        swale, waterway = drainage(seed, x0, y0, size, gsd_m)
        soil_v -= SWALE_SOIL * swale
        soil_v = np.clip(soil_v - 0.2 * (wet - 0.5), 0.0, 1.0)
        soil = _SOIL_DARK + (_SOIL_LIGHT - _SOIL_DARK) * soil_v[:, :, None]
        table = list(_STATES.values())
        plant = np.array([s[0] for s in table], np.float32)[state]
        cover = np.array([s[1] for s in table], np.float32)[state]
        rows_amp = np.array([s[2] for s in table], np.float32)[state]
        dark = np.array([s[3] for s in table], np.float32)[state]
        height = np.array([s[4] for s in table], np.float32)[state]
        code = np.array([s[5] for s in table], np.uint8)[state]
        # Growth varies over a field: with the soil (45 m, kept), and in patches of the
        # year's own (12 m: stand, weeds; DSIFN's fields share 0.02 of their 3-12 m texture).
        # The texture of annual plants and tilled clods is each year's own too.
        ref = year == REFERENCE_YEAR
        # The soil's zones show through the crop with each field's and year's own sign and
        # strength (ZONE_RESPONSE): the knob thin or lush, the 45 m vigour pattern either way.
        resp = (2.0 * field_unit(seed, f.key, year, 16) - 1.0)[f.fid]
        vigour = 0.12 * resp * value_noise(k + 1, x0 + 0.5, y0 + 0.5, size, 45.0 / gsd_m)
        kv = k + 2 if ref else key_of(seed, 0xF14, year)
        vigour += 0.06 * value_noise(kv, x0 + 0.5, y0 + 0.5, size, 12.0 / gsd_m)
        share = changed_share(years_since_reference(date), FIELD_EVERY_YEARS)
        managed = (field_unit(seed, f.key, 0, 11)[f.fid] < share) if share > 0.0 else None
        if managed is not None:  # fields farmed otherwise since the reference survey: the
            # year's growth pattern (seeding, manure, drainage) and brightness
            ky = key_of(seed, 0xF11, year)
            grown = 0.2 * value_noise(ky, x0 + 0.5, y0 + 0.5, size, 30.0 / gsd_m)
            grown += 0.1 * value_noise(ky + 1, x0 + 0.5, y0 + 0.5, size, 9.0 / gsd_m)
            vigour = np.where(managed, grown, vigour)
        vigour -= KNOB_CROP * resp * (soil_v - 0.5)
        if stage == "midsummer":  # a dry summer: dryland crops thin, irrigated ones green
            vigour -= 0.8 * max(0.0, 0.45 - wet)
        cover = np.clip(cover * (1.0 + vigour) + 0.15 * (f.pivot * running * (cover > 0.2)), 0, 1)
        # Plants and clods at 0.5-3 m: the grain of a field on 0.6 m imagery.
        detail = np.float32(min(1.0, 0.6 / gsd_m))
        tk = k + 4 if ref else key_of(seed, 0xF13, year)
        tex = fractal_noise(tk, x0, y0, size, 1.6 / gsd_m, 2) * detail
        cover = np.clip(cover * (1.0 + 0.12 * tex), 0.0, 1.0)
        soil = soil * (1.0 - 0.05 * tex)[:, :, None]
        stripes = _rows(seed, g, f, year, gsd_m, state)
        cover = np.clip(cover * (1.0 + rows_amp * stripes * 1.6), 0.0, 1.0)
        ground = (
            soil / dark[:, :, None] * (1.0 - 0.5 * rows_amp * stripes * (cover < 0.3))[:, :, None]
        )
        tone = 1.0 + FIELD_YEAR_TONE * (field_unit(seed, f.key, year, 9)[f.fid] - 0.5)
        if managed is not None:
            swing = FIELD_TONE * (2.0 * field_unit(seed, f.key, year, 12) - 1.0)
            tone *= 1.0 + managed * swing[f.fid]
        tone = tone * (1.0 - SWALE_CROP * (0.5 - wet) / 0.35 * swale * cover)
        col = (plant * cover[:, :, None] + ground * (1.0 - cover[:, :, None])) * tone[:, :, None]
        lay.col = col.astype(np.float32)
        # Grassed waterways along the drainage lines, through the cropped fields.
        grassed = (waterway * ((f.pivot < 0.5) & ~f.pasture)).astype(np.float32)
        if grassed.any():
            pick = field_unit(seed, f.key, year, 15)[f.fid] * 3.0
            pick = np.where(wet < 0.35, 3.0, pick).astype(np.int64)
            grass = _WATERWAY[pick] * (1.0 + 0.1 * tex)[:, :, None]
            lay.col = lay.col * (1.0 - grassed[:, :, None]) + grass * grassed[:, :, None]
            code = np.where(grassed > 0.5, np.uint8(GRASS), code)
        lay.code = code
        lay.height = (height * (cover > 0.3) * (grassed < 0.5)).astype(np.float32)
        self._pivots(lay, g, f, date)
        self._water(lay, date, wet, basin_wetness(seed, year))
        gravel, paved, ditch = roads(seed, g, gsd_m)
        lay.paint(ditch.astype(np.float32), _DITCH[season], GRASS)
        lay.height *= (1.0 - ditch).astype(np.float32)
        lay.paint(gravel.astype(np.float32), GRAVEL_BGR, GRAVEL)
        lay.paint(paved.astype(np.float32), ASPHALT_BGR, PAVED)
        if gsd_m <= 1.5:
            self._markings(lay, g, gsd_m)
        farmsteads(seed, lay, date)
        towns(seed, lay, date)
        self._canopy(lay, date)
        return lay

    def _pivots(self, lay: Layers, g: Grid, f: Fields, date: DateLook) -> None:
        """Corners of pivot quarters in grass, wheel tracks, the arm where it stopped."""
        is_pivot = np.isfinite(f.pivot_r_m)
        if not is_pivot.any():
            return
        corner = (1.0 - f.pivot) * is_pivot
        lay.paint(corner.astype(np.float32), _DITCH[date.season], GRASS)
        lay.height *= (1.0 - corner).astype(np.float32)
        r = np.where(is_pivot, f.pivot_r_m, 0.0)
        gsd = lay.gsd_m
        ring = np.abs(r - np.round(r / PIVOT_RING_M) * PIVOT_RING_M)
        tracks = (band(np.abs(ring - 1.5), 0.5, gsd) * (r > 20.0) * f.pivot).astype(np.float32)
        lay.col *= (1.0 - 0.25 * tracks)[:, :, None]
        # The arm: a steel truss from the centre toward where it stood during the survey.
        qi, qj = g.qi[None, :], g.qj[:, None]
        angle = 2.0 * math.pi * unit2(qi, qj, key_of(self.seed, 0xF20, date.index))
        de = g.a[None, :] - QUARTER_M / 2.0
        dn = g.b[:, None] - QUARTER_M / 2.0
        across = np.abs(de * np.sin(angle) - dn * np.cos(angle))
        along = de * np.cos(angle) + dn * np.sin(angle)
        arm = band(across, 0.7, gsd) * (along > 0.0) * (along < QUARTER_M / 2.0 - 14.0)
        hub = band(np.hypot(de, dn), 5.0, gsd)
        lay.paint((arm * is_pivot).astype(np.float32), (200, 204, 206), 10)
        lay.paint((hub * is_pivot).astype(np.float32), GRAVEL_BGR, GRAVEL)

    def _water(self, lay: Layers, date: DateLook, wet: float, full: float) -> None:
        """The creek (water, trees and grass along it) and the potholes: cattails round the
        basin, mud where the water receded, open water up to the level of the basins'
        several years (``full``); a dry year (``wet``) farms the shallow basins through."""
        seed, x0, y0, size, gsd = self.seed, lay.x0, lay.y0, lay.size, lay.gsd_m
        season = date.season
        p = pothole(seed, x0, y0, size, gsd)
        level = water_level(full)
        if float(p.max()) > -0.05:
            soft = max(0.02, 0.6 * gsd / 60.0)
            basin = np.clip((p + 0.05) / soft, 0.0, 1.0)
            # A dry year: cropped fields are farmed through the shallow basins.
            farmed = (lay.code <= SOY) & (wet < 0.45) & (p < level + 0.1)
            lay.paint((basin * ~farmed).astype(np.float32), _CATTAIL[season], WETLAND)
            mud = np.clip((p - level + 0.12) / soft, 0.0, 1.0) * basin
            lay.paint(mud.astype(np.float32), tuple(_MUD.tolist()), WETLAND)
            water = np.clip((p - level) / soft, 0.0, 1.0)
            lay.paint(water.astype(np.float32), tuple(_WATER.tolist()), WATER)
            lay.height *= (1.0 - basin).astype(np.float32)
        d = creek_distance_m(seed, x0, y0, size, gsd)
        if float(d.min()) > 80.0:
            return
        k = key_of(seed, 0xF30)
        buf = 34.0 + 14.0 * value_noise(k, x0 + 0.5, y0 + 0.5, size, 160.0 / gsd)
        lay.paint(np.clip((buf - d) / gsd + 0.5, 0, 1).astype(np.float32), _DITCH[season], GRASS)
        lay.height *= (d > buf).astype(np.float32)
        woods = np.clip((buf - 8.0 - d) / gsd + 0.5, 0, 1) * (
            value_noise(k + 1, x0 + 0.5, y0 + 0.5, size, 300.0 / gsd) > -0.5
        )
        lay.trees = np.maximum(lay.trees, 0.8 * woods).astype(np.float32)
        lay.tree_h = np.maximum(lay.tree_h, 15.0 * (woods > 0)).astype(np.float32)
        half = (1.5 + 5.0 * full) * (
            1.0 + 0.3 * value_noise(k + 2, x0 + 0.5, y0 + 0.5, size, 80.0 / gsd)
        )
        bank = np.clip((half + 2.5 - d) / gsd + 0.5, 0, 1)
        lay.paint(bank.astype(np.float32), tuple(_MUD.tolist()), WETLAND)
        lay.paint(
            np.clip((half - d) / gsd + 0.5, 0, 1).astype(np.float32), tuple(_WATER.tolist()), WATER
        )
        lay.trees *= (1.0 - bank).astype(np.float32)

    def _markings(self, lay: Layers, g: Grid, gsd: float) -> None:
        """The highway's yellow centre line (dashed) and white edge lines."""
        hwy = is_highway(self.seed, g.line_i)
        if not hwy.any():
            return
        dash = (np.mod(g.n, 12.0) < 3.0)[:, None]
        centre = (band(g.du, 0.08, gsd) * hwy)[None, :] * dash
        edge = (band(np.abs(g.du - HIGHWAY_HALF_M), 0.08, gsd) * hwy)[None, :] * np.ones_like(dash)
        lay.paint(centre.astype(np.float32), (40, 190, 220), PAVED)
        lay.paint(edge.astype(np.float32), (225, 228, 230), PAVED)

    def _canopy(self, lay: Layers, date: DateLook) -> None:
        """Trees where asked for (shelterbelts, creek woods, town): crowns from noise, lit
        on their sunny side, bare in spring (the conifers of the belts stay green)."""
        if not lay.trees.any():
            return
        x0, y0, size, gsd = lay.x0, lay.y0, lay.size, lay.gsd_m
        k = key_of(self.seed, 0xF40)
        season = date.season
        conifer = value_noise(k + 3, x0 + 0.5, y0 + 0.5, size, 40.0 / gsd) > 0.6
        leaves = np.where(
            conifer[:, :, None],
            np.array(_CONIFER, np.float32),
            np.array(_LEAVES[season], np.float32),
        )
        if gsd <= CANOPY_MAX_GSD_M:
            blob = value_noise(k, x0 + 0.5, y0 + 0.5, size, 3.5 / gsd)
            blob += 0.5 * value_noise(k + 1, x0 + 0.5, y0 + 0.5, size, 2.0 / gsd)
            wanted = lay.trees * (1.0 + 0.45 * blob)
            present = np.clip((wanted - 0.4) / 0.12, 0.0, 1.0)
            # Crowns as domes: the height rises over a few metres from the crown's rim.
            rim = np.sqrt(np.clip((wanted - 0.34) / 0.3, 0.0, 1.0))
            h = lay.tree_h * np.clip(0.82 + 0.12 * blob, 0.5, 1.0) * rim
            grad = np.gradient(h.astype(np.float32), gsd)
            sun_e, sun_n = date.sun_dir()
            lit = np.clip(1.0 + 0.25 * (grad[1] * sun_e - grad[0] * sun_n), 0.6, 1.4)
            if date.leaf_off:
                lit = np.where(conifer, lit, 1.0 + 0.3 * (lit - 1.0))
                present = np.where(conifer, present, 0.55 * present)
            tone = leaves * lit[:, :, None]
        else:
            present = np.clip(lay.trees * 0.85, 0.0, 1.0).astype(np.float32)
            h = (lay.tree_h * present).astype(np.float32)
            tone = (leaves * np.float32(0.85)).astype(np.float32)
        c = present[:, :, None].astype(np.float32)
        lay.col = (lay.col * (1.0 - c) + tone * c).astype(np.float32)
        lay.height = np.maximum(lay.height, h.astype(np.float32))
        lay.code = np.where(present > 0.5, np.uint8(TREES), lay.code)


def _field_state(
    seed: int,
    key: npt.NDArray[np.uint64],
    fid: npt.NDArray[np.int64],
    crop: npt.NDArray[np.int64],
    prev: npt.NDArray[np.int64],
    year: int,
    stage: str,
    wet: float,
) -> npt.NDArray[np.int64]:
    """Index into ``_STATES`` of each field in this survey: the year's crop at its stage
    (:func:`_stage`: harvested yet, tilled, cut), in spring the residue of last year's crop."""
    s = _STATE_NAMES.index
    u = field_unit(seed, key, year, 1 if stage != "spring" else 2)[fid]
    v = field_unit(seed, key, year, 3)[fid]
    if stage == "midsummer":  # July-August: wheat cut in July, alfalfa cut every 5 weeks
        pairs = [
            (crop == CORN, "corn_tall"), (crop == SOY, "soy_full"),
            ((crop == WHEAT) & (v < 0.4), "tilled"), (crop == WHEAT, "wheat_stubble"),
            ((crop == ALFALFA) & (u < 0.4), "alfalfa_cut"), (crop == ALFALFA, "alfalfa"),
        ]  # fmt: skip
        default = "grass_dry" if wet < 0.35 else "grass"
    elif stage == "june":
        pairs = [
            (crop == CORN, "corn_june"), (crop == SOY, "soy_june"), (crop == WHEAT, "wheat_ripe"),
            ((crop == ALFALFA) & (u < 0.35), "alfalfa_cut"), (crop == ALFALFA, "alfalfa"),
        ]  # fmt: skip
        default = "grass"
    elif stage == "autumn":
        harvested = ((crop == CORN) & (u < 0.45)) | ((crop == SOY) & (u < 0.75))
        pairs = [
            (harvested & (v < 0.25), "tilled"), ((crop == CORN) & harvested, "corn_residue"),
            (crop == CORN, "corn_dry"), ((crop == SOY) & harvested, "soy_residue"),
            (crop == SOY, "soy_dry"), ((crop == WHEAT) & (v < 0.4), "tilled"),
            (crop == WHEAT, "wheat_stubble"), (crop == ALFALFA, "alfalfa"),
        ]  # fmt: skip
        default = "grass_dry"
    else:  # spring: wheat, alfalfa and grass green; last year's residue, tilled or planted
        pairs = [
            (crop == WHEAT, "wheat_green"), (crop == ALFALFA, "alfalfa"),
            (crop == GRASS, "grass_spring"), (u < 0.3, "tilled"), (u < 0.42, "planted"),
            (prev == CORN, "corn_residue"), (prev == SOY, "soy_residue"),
            (prev == WHEAT, "wheat_stubble"),
        ]  # fmt: skip
        default = "grass_spring"
    return np.select([c for c, _ in pairs], [s(n) for _, n in pairs], s(default))


def _stage(date: DateLook) -> str:
    """The crops' stage in a survey: ``june``, ``midsummer`` (July-August), ``autumn``,
    ``spring``."""
    if date.season == "summer":
        return "june" if int(date.label[5:7]) <= 6 else "midsummer"
    return date.season


def _rows(
    seed: int, g: Grid, f: Fields, year: int, gsd_m: float, state: npt.NDArray[np.int64]
) -> FloatImage:
    """Row stripes (-1..1) of each field: across the field in the year's direction, along
    the field's edges in the headlands, in circles on pivots."""
    period = _ROW_PERIOD_M
    fade = float(np.clip(1.0 - (2.2 * gsd_m / period) ** 2, 0.0, 1.0))
    if fade == 0.0:
        return np.zeros(state.shape, np.float32)
    kept = field_unit(seed, f.key, 0, 14) < ROWS_KEPT  # the reference year's direction
    direction = field_unit(seed, f.key, np.where(kept, REFERENCE_YEAR, year), 4)
    east_rows = (direction[f.fid] < 0.7) == f.along_e
    coord = np.where(
        east_rows, g.b[:, None] + 0.0 * g.a[None, :], g.a[None, :] + 0.0 * g.b[:, None]
    )
    coord = np.where(f.edge_m < _HEADLAND_M, f.edge_m, coord)
    coord = np.where(np.isfinite(f.pivot_r_m) & (f.pivot > 0.5), f.pivot_r_m, coord)
    phase = field_unit(seed, f.key, year, 5)[f.fid] * period
    out: FloatImage = (fade * np.sin(2.0 * math.pi * (coord + phase) / period)).astype(np.float32)
    return out
