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
BLOCK_PX = 16  # level-0 heights per side of a block kept for point samples (15 x 15 cells)


class HeightBlock:
    """Level-0 heights [y0, y0+n) x [x0, x0+n) as Python floats: a flight samples the ground
    at every physics step, centimetres apart, so one block serves many steps."""

    __slots__ = ("rows", "x0", "y0")

    def __init__(self, x0: int, y0: int, heights: Heights) -> None:
        self.x0, self.y0 = x0, y0
        self.rows: list[list[float]] = heights.astype(np.float64).tolist()

    @staticmethod
    def origin(ix: int, iy: int, n: int = BLOCK_PX) -> tuple[int, int]:
        """The block origin whose cells hold cell (ix, iy) (blocks overlap by one height)."""
        return (ix // (n - 1)) * (n - 1), (iy // (n - 1)) * (n - 1)

    def at(self, x_px: float, y_px: float) -> float | None:
        """Bilinear height at a continuous level-0 pixel; None outside the block's cells."""
        ix, iy = math.floor(x_px), math.floor(y_px)
        i, j = ix - self.x0, iy - self.y0
        rows = self.rows
        if not (0 <= j < len(rows) - 1 and 0 <= i < len(rows[0]) - 1):
            return None
        fx, fy = x_px - ix, y_px - iy
        r0, r1 = rows[j], rows[j + 1]
        top = r0[i] * (1 - fx) + r0[i + 1] * fx
        bottom = r1[i] * (1 - fx) + r1[i + 1] * fx
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

    def ground_and_surface_at(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """``terrain_at`` and ``height_at`` of one position at once."""
        ...

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests."""
        ...


_WARNED: set[str] = set()  # warnings said (TiledSurface.warn)


class TiledSurface:
    """Base of every surface: float32 tiles per (level, tx, ty) of the map grid, cached."""

    name: str

    def __init__(self, map_source: MapSource, cache_bytes: int = SURFACE_CACHE_BYTES) -> None:
        self.map = map_source
        self._cache = TileCache(cache_bytes)
        self._block: HeightBlock | None = None  # around the last point sampled

    def _make_tile(self, level: int, tx: int, ty: int) -> Heights:
        """Heights (TILE_PX x TILE_PX) of tile (tx, ty) of level ``level``."""
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests."""
        raise NotImplementedError

    def warn(self, text: str) -> None:
        """One line on stderr, once per distinct text in the process (a flight opens its DEM
        more than once: home's ground, the flight's terrain, the camera's surface; the
        library configures no logging)."""
        if text not in _WARNED:
            _WARNED.add(text)
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
        block = self._block  # one read: other threads may replace it meanwhile
        h = None if block is None else block.at(x_px, y_px)
        if h is None:
            x0, y0 = HeightBlock.origin(math.floor(x_px), math.floor(y_px))
            block = self._block = HeightBlock(x0, y0, self.heights(0, x0, y0, BLOCK_PX, BLOCK_PX))
            h = block.at(x_px, y_px)
            assert h is not None
        return h

    def height_at(self, lat_deg: float, lon_deg: float) -> float:
        """Height under a WGS84 position."""
        x, y = self.map.latlon_to_map_px(lat_deg, lon_deg)
        return self.height_at_map_px(x, y)

    def terrain_at_map_px(self, x_px: float, y_px: float) -> float:
        """The ground at a continuous level-0 map pixel: the surface itself, unless a subclass
        knows the bare terrain beneath its objects."""
        return self.height_at_map_px(x_px, y_px)

    def terrain_at(self, lat_deg: float, lon_deg: float) -> float:
        """The ground under a WGS84 position (:meth:`terrain_at_map_px`)."""
        x, y = self.map.latlon_to_map_px(lat_deg, lon_deg)
        return self.terrain_at_map_px(x, y)

    def ground_and_surface_at(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """The ground and the surface under a WGS84 position, converted to the map once (a
        flight asks at every physics step)."""
        x, y = self.map.latlon_to_map_px(lat_deg, lon_deg)
        return self.terrain_at_map_px(x, y), self.height_at_map_px(x, y)

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
