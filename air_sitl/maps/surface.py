"""Surface models: heights above mean sea level on a map's own pixel grid, by pyramid level.

A surface belongs to one map: its heights are sampled at the centres of that map's level-L
pixels (the convention of :mod:`air_sitl.maps.base`), so the renderer marches rays over the
same grid it takes colours from. Sources: a GeoTIFF elevation model of any CRS
(:class:`~air_sitl.maps.dem.GeoTiffDem`), the built-in procedural surfaces
(:class:`~air_sitl.maps.procedural.surface.ProceduralSurface`), and a flat plane.
Tiles are float32, cached like the map's (bounded LRU).
"""

from __future__ import annotations

import math
import sys
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from air_sitl.maps.base import TILE_PX, MapSource, TileCache, paste_tiles

Heights = npt.NDArray[np.float32]
SURFACE_CACHE_BYTES = 96 * 1024 * 1024
# One level-0 cell: (ix, iy, h00, h01, h10, h11), its corner heights as floats.
Cell = tuple[int, int, float, float, float, float]


def cell_of(ix: int, iy: int, h: Heights) -> Cell:
    """The cell at (ix, iy) from its 2 x 2 corner heights."""
    h64 = h.astype(np.float64)
    return (ix, iy, float(h64[0, 0]), float(h64[0, 1]), float(h64[1, 0]), float(h64[1, 1]))


def bilinear(cell: Cell, x_px: float, y_px: float) -> float:
    """Height inside ``cell`` at a continuous level-0 pixel (its own cell's)."""
    fx, fy = x_px - cell[0], y_px - cell[1]
    top = cell[2] * (1 - fx) + cell[3] * fx
    bottom = cell[4] * (1 - fx) + cell[5] * fx
    return top * (1 - fy) + bottom * fy


@runtime_checkable
class SurfaceModel(Protocol):
    """Heights (AMSL metres) of the first surface seen from above: terrain, roofs, canopy."""

    name: str

    def heights(self, level: int, x0: int, y0: int, width: int, height: int) -> Heights:
        """Heights at level-``level`` pixel centres [y0, y0+height) x [x0, x0+width)."""
        ...

    def height_at_map_px(self, x_px: float, y_px: float) -> float:
        """Height at a continuous level-0 map pixel (bilinear)."""
        ...

    def height_at(self, lat_deg: float, lon_deg: float) -> float:
        """Height under a WGS84 position."""
        ...

    def terrain_at(self, lat_deg: float, lon_deg: float) -> float:
        """Height of the ground under a WGS84 position: where wheels roll (no roofs, no
        crowns where the model can tell them apart; a DEM file is taken as the ground)."""
        ...

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests."""
        ...


class TiledSurface:
    """Base of every surface: float32 tiles per (level, tx, ty) of the map grid, cached."""

    name: str

    def __init__(self, map_source: MapSource, cache_bytes: int = SURFACE_CACHE_BYTES) -> None:
        self.map = map_source
        self._cache = TileCache(cache_bytes)
        self._warned: set[str] = set()
        # The level-0 cell of the last point sampled (ix, iy, h00, h01, h10, h11): a flight
        # samples every physics step, mostly within one cell.
        self._cell: Cell | None = None

    def _make_tile(self, level: int, tx: int, ty: int) -> Heights:
        """Heights (TILE_PX x TILE_PX) of tile (tx, ty) of level ``level``."""
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests."""
        raise NotImplementedError

    def warn(self, text: str) -> None:
        """One line on stderr, once per distinct text (the library configures no logging)."""
        if text not in self._warned:
            self._warned.add(text)
            print(f"air-sitl: warning: {text}", file=sys.stderr, flush=True)

    def tile(self, level: int, tx: int, ty: int) -> Heights:
        """One tile, from the cache or made now."""
        key = (level, tx, ty)
        got = self._cache.get(key)
        if got is not None:
            return got  # type: ignore[return-value]
        tile = np.ascontiguousarray(self._make_tile(level, tx, ty), dtype=np.float32)
        tile.setflags(write=False)
        self._cache.put(key, tile)  # type: ignore[arg-type]
        return tile

    def heights(self, level: int, x0: int, y0: int, width: int, height: int) -> Heights:
        """Heights at level-``level`` pixel centres [y0, y0+height) x [x0, x0+width)."""
        out = np.empty((height, width), dtype=np.float32)
        paste_tiles(out, lambda tx, ty: self.tile(level, tx, ty), x0, y0)
        return out

    def height_at_map_px(self, x_px: float, y_px: float) -> float:
        """Height at a continuous level-0 map pixel (bilinear over the level-0 tiles)."""
        ix, iy = math.floor(x_px), math.floor(y_px)
        cell = self._cell  # one read: other threads may replace it meanwhile
        if cell is None or cell[0] != ix or cell[1] != iy:
            cell = self._cell = cell_of(ix, iy, self.heights(0, ix, iy, 2, 2))
        return bilinear(cell, x_px, y_px)

    def height_at(self, lat_deg: float, lon_deg: float) -> float:
        """Height under a WGS84 position."""
        x, y = self.map.latlon_to_map_px(lat_deg, lon_deg)
        return self.height_at_map_px(x, y)

    def terrain_at(self, lat_deg: float, lon_deg: float) -> float:
        """The ground under a WGS84 position: the surface itself, unless a subclass knows the
        bare terrain beneath its objects."""
        return self.height_at(lat_deg, lon_deg)

    def level_centres_crs(
        self, level: int, tx: int, ty: int, n: int = TILE_PX
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Map-CRS coordinates of the centres of a tile's pixels (n x n grid, n <= TILE_PX)."""
        s = 1 << level
        step = (TILE_PX - 1) / max(n - 1, 1)
        i = tx * TILE_PX + np.arange(n) * step
        j = ty * TILE_PX + np.arange(n) * step
        col = s * i + (s - 1) / 2.0 + 0.5  # level-0 continuous -> pixel-corner coordinates
        row = s * j + (s - 1) / 2.0 + 0.5
        t0, t1, t2, t3, t4, t5 = self.map.georef.transform
        cc, rr = np.meshgrid(col, row)
        return t0 + t1 * cc + t2 * rr, t3 + t4 * cc + t5 * rr


class FlatSurface(TiledSurface):
    """The plane at one elevation (the flat world, as a surface; tests)."""

    def __init__(self, map_source: MapSource, elevation_m: float) -> None:
        super().__init__(map_source, cache_bytes=4 * TILE_PX * TILE_PX * 8)
        self.elevation_m = float(elevation_m)
        self.name = f"flat-{elevation_m:g}m"

    def _make_tile(self, level: int, tx: int, ty: int) -> Heights:
        return np.full((TILE_PX, TILE_PX), self.elevation_m, dtype=np.float32)

    def describe(self) -> dict[str, Any]:
        """Provenance: a plane."""
        return {"source": "flat", "elevation_m": self.elevation_m}
