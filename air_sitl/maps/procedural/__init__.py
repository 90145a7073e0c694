"""Built-in procedural maps (``urban``, ``forest``, ``farmland``): unbounded, deterministic,
several dates.

The world is a function of absolute UTM coordinates (zone of home), seed and date, so two
flights with different homes in one area see the same ground, and ``map make`` writes the same
pixels. Nominal level-0 pixel grid (what MapX/MapY count): ``gsd_m`` metres per pixel (default
0.6), pixel edges on multiples of ``gsd_m`` in UTM, origin ``NOMINAL_HALF_PX`` pixels west and
north of the 256-pixel lattice cell that holds home; so home lies at pixel
(5120 + a, 5120 + b) with 0 <= a, b < 256, and ``air-sitl map make`` with its default size and
``--origin`` = home writes exactly that grid (10240 x 10240 pixels). One exception to "the
world ignores home": the forest keeps lakes 2 km away from home, so flights start over land.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from air_sitl.maps.base import (
    DEFAULT_CACHE_BYTES,
    TILE_PX,
    Georeference,
    Image,
    TiledMap,
    downsample2,
    map_error,
)
from air_sitl.maps.procedural.canvas import DateLook, dates_of
from air_sitl.maps.procedural.farmland import FarmlandWorld
from air_sitl.maps.procedural.forest import ForestWorld
from air_sitl.maps.procedural.shared_tiles import SharedSurveys
from air_sitl.maps.procedural.survey import acquire, displacement_m
from air_sitl.maps.procedural.urban import UrbanWorld
from air_sitl.maps.utm import latlon2utm, utm_zone_of
from air_sitl.state import GeoPoint

KINDS = ("urban", "forest", "farmland")
DEFAULT_GSD_M = 0.6
NOMINAL_HALF_PX = 5120
NUM_LEVELS = 9  # level 8 is 256 x gsd per pixel (154 m at 0.6 m)
# From this level up, tiles are drawn directly at the next finer level's resolution and
# low-passed once, instead of from 4**level level-0 tiles: high flights see new ground at
# about the cost of low ones. Finer levels are exact reductions of level 0.
DIRECT_FROM_LEVEL = 3


def parse_date(value: str | int | None, kind: str | None = None) -> DateLook:
    """A date of a procedural map (of world ``kind``: :func:`dates_of`) from an index ("0",
    "1", ...), a label ("2012-10-08", or with its local solar time "2012-10-08 14:20") or a
    season; its sun at the default latitude."""
    dates = dates_of(kind)
    if value is None:
        return dates[0]
    text = str(value).strip()
    for look in dates:
        if text in (str(look.index), look.label, look.full_label, look.season):
            return look
    names = ", ".join(f"{d.index}={d.full_label} ({d.season})" for d in dates)
    world = f"the {kind} map" if kind in KINDS else "the procedural maps"
    raise map_error("--map-date", f"{text!r} is not a date of {world} ({names})")


class ProceduralMap(TiledMap):
    """One date of the ``urban``, ``forest`` or ``farmland`` world around ``home``."""

    def __init__(
        self,
        kind: str,
        home: GeoPoint,
        *,
        seed: int = 0,
        date: str | int | None = None,
        gsd_m: float = DEFAULT_GSD_M,
        cache_bytes: int = DEFAULT_CACHE_BYTES,
        shared_dir: Path | None = None,
    ) -> None:
        """``shared_dir``: a folder where the processes of one run share the drawn ground
        (:mod:`.shared_tiles`); None draws everything here."""
        super().__init__(cache_bytes)
        if kind not in KINDS:
            raise map_error("--map", f"{kind!r} is not a procedural map ({', '.join(KINDS)})")
        if not (gsd_m > 0.05 and math.isfinite(gsd_m)):
            raise map_error("--gsd-m", f"{gsd_m!r} is not a ground sample distance >= 0.05 m")
        self.kind = kind
        self.seed = int(seed)
        self.date = parse_date(date, kind).at_latitude(home.lat_deg)
        self.zone = utm_zone_of(home.lat_deg, home.lon_deg)
        e, n = latlon2utm(home.lat_deg, home.lon_deg, self.zone)
        self._world: UrbanWorld | ForestWorld | FarmlandWorld = (
            UrbanWorld(self.seed)
            if kind == "urban"
            else FarmlandWorld(self.seed)
            if kind == "farmland"
            else ForestWorld(self.seed, (e, n))
        )
        # Absolute lattice: pixel k spans [k, k+1) * gsd east and [-k-1, -k) * gsd north.
        cell_x = math.floor(e / gsd_m / TILE_PX) * TILE_PX
        cell_y = math.floor(-n / gsd_m / TILE_PX) * TILE_PX
        self.origin_abs_px = (cell_x - NOMINAL_HALF_PX, cell_y - NOMINAL_HALF_PX)
        ox, oy = self.origin_abs_px
        self.name = f"{kind}-seed{self.seed}-{self.date.label}"
        self.georef = Georeference(
            crs=f"EPSG:{self.zone.epsg}",
            transform=(ox * gsd_m, gsd_m, 0.0, -oy * gsd_m, 0.0, -gsd_m),
            width_px=None,
            height_px=None,
            gsd_m=gsd_m,
        )
        self.ground_elevation_m = home.alt_amsl_m
        self.num_levels = NUM_LEVELS
        self._gsd = gsd_m
        self.home_px = self.latlon_to_map_px(home.lat_deg, home.lon_deg)
        identity = (kind, self.seed, self.date, gsd_m, e, n, self.zone.epsg)
        self._shared = None if shared_dir is None else SharedSurveys(shared_dir, identity)

    @property
    def world(self) -> UrbanWorld | ForestWorld | FarmlandWorld:
        """The generator (its ``objects`` give the built-in surface's roofs and canopy)."""
        return self._world

    def _latlon_to_crs(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        return latlon2utm(lat_deg, lon_deg, self.zone)

    def _made_together(self, level: int, tx: int, ty: int) -> tuple[int, int, int]:
        if 0 < level < DIRECT_FROM_LEVEL:
            return (level, tx, ty)  # from four finer tiles, alone
        return (level, tx - tx % 2, ty - ty % 2)  # the 2x2 group of _make_tile, _native_tile

    def _make_tile(self, tx: int, ty: int) -> Image:
        # Draw the 2x2 group holding this tile at once: the margin every tile must draw
        # around itself (shadows, crowns crossing the edge) is then paid once for four.
        gx, gy = tx - tx % 2, ty - ty % 2
        ox, oy = self.origin_abs_px
        bgr = self.render_abs(ox + gx * TILE_PX, oy + gy * TILE_PX, 2 * TILE_PX)
        return self._split_group(0, gx, gy, tx, ty, bgr)

    def _native_tile(self, level: int, tx: int, ty: int) -> Image | None:
        if level < DIRECT_FROM_LEVEL:
            return None
        gx, gy = tx - tx % 2, ty - ty % 2
        ox, oy = self.origin_abs_px
        fine = level - 1
        # The group's 2x2 tiles at `level` cover 4x4 tiles of `fine`: draw those at once.
        x0 = (ox >> fine) + 2 * gx * TILE_PX
        y0 = (oy >> fine) + 2 * gy * TILE_PX
        bgr = self._acquire(x0, y0, 4 * TILE_PX, self._gsd * (1 << fine))
        small = downsample2(np.ascontiguousarray(bgr))
        return self._split_group(level, gx, gy, tx, ty, small)

    def _split_group(self, level: int, gx: int, gy: int, tx: int, ty: int, bgr: Image) -> Image:
        """Cut a 2x2-tile BGR block into BGRx tiles; cache the siblings, return (tx, ty)."""
        mine: Image | None = None
        for dy in (0, 1):
            for dx in (0, 1):
                tile = np.empty((TILE_PX, TILE_PX, 4), dtype=np.uint8)
                tile[:, :, :3] = bgr[
                    dy * TILE_PX : (dy + 1) * TILE_PX, dx * TILE_PX : (dx + 1) * TILE_PX
                ]
                tile[:, :, 3] = 255
                if (gx + dx, gy + dy) == (tx, ty):
                    mine = tile
                else:
                    tile.setflags(write=False)
                    self._cache.put((level, gx + dx, gy + dy), tile)
        assert mine is not None
        return mine

    def render_abs(self, x0_abs: int, y0_abs: int, size: int) -> Image:
        """Level-0 BGR pixels of a square at absolute lattice position (used by ``map make``)."""
        return self._acquire(x0_abs, y0_abs, size, self._gsd)

    def _acquire(self, x0_abs: int, y0_abs: int, size: int, gsd_m: float) -> Image:
        """This date's survey of the world over a square of the lattice at ``gsd_m``."""

        def draw() -> Image:
            return acquire(self._world.draw, self.seed, x0_abs, y0_abs, size, gsd_m, self.date)

        if self._shared is None:
            return draw()
        return self._shared.square(x0_abs, y0_abs, size, gsd_m, draw)

    def misregistration_m(self, x_px: float, y_px: float) -> tuple[float, float]:
        """(dE, dN) metres by which this date's orthophoto shows, at level-0 map pixel
        (x_px, y_px), the ground that truly lies that far east and north: its survey's
        misregistration (0 on date 0, the reference survey)."""
        ox, oy = self.origin_abs_px
        d = displacement_m(
            self.seed, self.date, ox + math.floor(x_px), oy + math.floor(y_px), 1, self._gsd
        )
        return (0.0, 0.0) if d is None else (float(d[0][0, 0]), float(d[1][0, 0]))

    def read_bgr(self, x0: int, y0: int, width: int, height: int) -> Image:
        """Level-0 BGR pixels of a window of the nominal grid (tiles cached as usual)."""
        return np.ascontiguousarray(self.read_level(0, x0, y0, width, height)[:, :, :3])

    def describe(self) -> dict[str, Any]:
        """Provenance: kind, seed, date, grid."""
        return {
            "source": "procedural",
            "kind": self.kind,
            "seed": self.seed,
            "date": self.date.label,
            "date_index": self.date.index,
            "solar_time": self.date.solar_time,
            "season": self.date.season,
            "sun_azimuth_deg": self.date.sun_azimuth_deg,
            "sun_elevation_deg": self.date.sun_elevation_deg,
            "crs": self.georef.crs,
            "transform": list(self.georef.transform),
            "gsd_m": self._gsd,
        }
