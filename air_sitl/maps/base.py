"""The map contract: georeference, pyramid levels read by window, lat/lon -> map pixels.

Pixel convention (every map, every level): the centre of pixel (col, row) is at the continuous
coordinate (col, row); the georeference ``transform`` (GDAL order) maps the pixel CORNER
(col, row) to CRS coordinates, so a pixel centre is at ``transform`` applied to
(col + 0.5, row + 0.5). Pyramid level L halves the resolution L times: level-L pixel i covers
level-0 pixels [i * 2**L, (i + 1) * 2**L), hence ``x0 = 2**L * xL + (2**L - 1) / 2``.

Pixels are 4-channel BGRx uint8 (OpenCV's vectorised warp path is about 3x faster on 4
channels than on 3, SPEC section 4). Areas outside a bounded map read as :data:`FILL_BGRX`.
The fourth channel is the coverage: 255 where the map has data, 0 outside a bounded map and
where a GeoTIFF says nodata (its nodata value, alpha band or mask); the colours stay as read.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.errors import MapError
from air_sitl.frames import ned2geodetic

TILE_PX = 256
FILL_BGRX: tuple[int, int, int, int] = (0, 0, 0, 0)
DEFAULT_CACHE_BYTES = 256 * 1024 * 1024

Image = npt.NDArray[np.uint8]
Affine6 = tuple[float, float, float, float, float, float]


@dataclass(frozen=True, slots=True, kw_only=True)
class Georeference:
    """Where level-0 pixels are: CRS, affine (GDAL order, pixel corner), size, metres/pixel."""

    crs: str  # "EPSG:32635" or a WKT string
    transform: Affine6  # x = t0 + t1*col + t2*row ; y = t3 + t4*col + t5*row
    width_px: int | None  # None: unbounded (procedural maps)
    height_px: int | None
    gsd_m: float  # ground metres per level-0 pixel near home

    def crs_to_px(self, x: float, y: float) -> tuple[float, float]:
        """CRS coordinates to continuous level-0 pixel coordinates (pixel centres integral)."""
        t0, t1, t2, t3, t4, t5 = self.transform
        det = t1 * t5 - t2 * t4
        dx, dy = x - t0, y - t3
        col = (t5 * dx - t2 * dy) / det
        row = (-t4 * dx + t1 * dy) / det
        return (col - 0.5, row - 0.5)

    def px_to_crs(self, col: float, row: float) -> tuple[float, float]:
        """Continuous level-0 pixel coordinates to CRS coordinates."""
        t0, t1, t2, t3, t4, t5 = self.transform
        c, r = col + 0.5, row + 0.5
        return (t0 + t1 * c + t2 * r, t3 + t4 * c + t5 * r)


@runtime_checkable
class MapSource(Protocol):
    """One date of one map: georeferenced pixels at several pyramid levels."""

    name: str
    georef: Georeference
    ground_elevation_m: float  # the ground plane the camera sees (AMSL metres)
    num_levels: int  # pyramid levels available: 0 .. num_levels - 1

    def latlon_to_map_px(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """Continuous level-0 pixel (x, y) of a WGS84 position (MapX/MapY are these rounded)."""
        ...

    def level_for_gsd(self, gsd_m: float) -> int:
        """The coarsest pyramid level whose pixels are no larger than ``gsd_m`` metres."""
        ...

    def read_level(self, level: int, x0: int, y0: int, width: int, height: int) -> Image:
        """Pixels [y0, y0+height) x [x0, x0+width) of level ``level`` as (h, w, 4) BGRx."""
        ...

    def read_ground(
        self, x0_m: float, y0_m: float, x1_m: float, y1_m: float, gsd_m: float
    ) -> MapPatch:
        """Pixels covering a CRS window at the level nearest ``gsd_m``, with their placement."""
        ...

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests: source kind, seed or file SHA-256, date."""
        ...


@dataclass(frozen=True, slots=True)
class MapPatch:
    """Pixels of one pyramid level and where their top-left pixel sits in that level's grid."""

    image: Image
    level: int
    x0_px: int
    y0_px: int


def level_scale(level: int) -> float:
    """Level-0 pixels per level-``level`` pixel."""
    return float(1 << level)


def downsample2(block: Image) -> Image:
    """Halve resolution with the binomial [1,3,3,1]/8 filter (zero response at Nyquist).

    Output pixel j is centred at input 2j + 0.5 (the box convention of the pyramid); a box
    filter (INTER_AREA) would pass half the amplitude at 2/3 Nyquist and alias at 3000 m.
    """
    kernel = np.array([1.0, 3.0, 3.0, 1.0], dtype=np.float32) / 8.0
    filtered = cv2.sepFilter2D(block, -1, kernel, kernel, borderType=cv2.BORDER_REFLECT)
    return np.ascontiguousarray(filtered[1::2, 1::2])


class TileCache:
    """A thread-safe LRU of tiles keyed by (level, tx, ty), bounded in bytes."""

    def __init__(self, capacity_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self.capacity_bytes = capacity_bytes
        self._tiles: OrderedDict[tuple[int, int, int], Image] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def get(self, key: tuple[int, int, int]) -> Image | None:
        """The tile, marked most recently used; None when absent."""
        with self._lock:
            tile = self._tiles.get(key)
            if tile is not None:
                self._tiles.move_to_end(key)
            return tile

    def put(self, key: tuple[int, int, int], tile: Image) -> None:
        """Store a tile, evicting the least recently used beyond the capacity."""
        with self._lock:
            if key in self._tiles:
                return
            self._tiles[key] = tile
            self._bytes += tile.nbytes
            while self._bytes > self.capacity_bytes and len(self._tiles) > 1:
                _, old = self._tiles.popitem(last=False)
                self._bytes -= old.nbytes

    @property
    def nbytes(self) -> int:
        """Bytes held."""
        return self._bytes


class TiledMap:
    """Base of every map: tiles per level, cached; coarse levels from finer ones when needed.

    Subclasses implement :meth:`_make_tile` for level 0 (and may serve coarser levels
    natively, e.g. from a GeoTIFF's overviews, by overriding :meth:`_native_tile`).
    """

    name: str
    georef: Georeference
    ground_elevation_m: float
    num_levels: int

    def __init__(self, cache_bytes: int = DEFAULT_CACHE_BYTES) -> None:
        self._cache = TileCache(cache_bytes)
        # One lock per tile being made: the camera's threads render consecutive frames, which
        # need the same new tiles at the same moment; the second waits for the first's tile
        # instead of making it again (procedural ground costs 0.3-0.5 s a 512-pixel square).
        self._making: dict[tuple[int, int, int], threading.Lock] = {}
        self._making_lock = threading.Lock()

    # -- to implement -----------------------------------------------------------------------
    def _make_tile(self, tx: int, ty: int) -> Image:
        """Level-0 tile (TILE_PX x TILE_PX x 4) at tile index (tx, ty)."""
        raise NotImplementedError

    def _native_tile(self, level: int, tx: int, ty: int) -> Image | None:
        """A coarser-level tile read directly, or None to build it from level - 1."""
        return None

    def _latlon_to_crs(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        raise NotImplementedError

    def describe(self) -> dict[str, Any]:
        """Provenance for manifests."""
        raise NotImplementedError

    # -- shared ----------------------------------------------------------------------------
    def latlon_to_map_px(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """Continuous level-0 pixel (x, y) of a WGS84 position."""
        x, y = self._latlon_to_crs(lat_deg, lon_deg)
        return self.georef.crs_to_px(x, y)

    def level_for_gsd(self, gsd_m: float) -> int:
        """Coarsest level whose pixels are no larger than ``gsd_m``: steps stay in [1, 2).

        Levels are low-passed with a binomial filter (zero response at their Nyquist), so a
        step below 2 level pixels does not alias visibly, and rounding down keeps the image
        as sharp as a single level allows.
        """
        if gsd_m <= self.georef.gsd_m:
            return 0
        level = math.floor(math.log2(gsd_m / self.georef.gsd_m) + 1e-9)
        return max(0, min(self.num_levels - 1, level))

    def level_size(self, level: int) -> tuple[int | None, int | None]:
        """Width and height in pixels of ``level`` (None when unbounded)."""
        w, h = self.georef.width_px, self.georef.height_px
        s = 1 << level
        return (None if w is None else -(-w // s), None if h is None else -(-h // s))

    def _made_together(self, level: int, tx: int, ty: int) -> tuple[int, int, int]:
        """The key of the tiles made at once with (level, tx, ty) (itself by default)."""
        return (level, tx, ty)

    def tile(self, level: int, tx: int, ty: int) -> Image:
        """One tile of one level, from the cache or made now (once, whichever thread asks:
        the others wait for it; a tile's finer tiles are made under their own locks, so the
        locks are taken from coarse to fine and never in a cycle)."""
        key = (level, tx, ty)
        tile = self._cache.get(key)
        if tile is not None:
            return tile
        group = self._made_together(level, tx, ty)
        with self._making_lock:
            lock = self._making.setdefault(group, threading.Lock())
        try:
            with lock:
                tile = self._cache.get(key)
                return tile if tile is not None else self._make(level, tx, ty)
        finally:
            with self._making_lock:
                if self._making.get(group) is lock and not lock.locked():
                    del self._making[group]

    def _make(self, level: int, tx: int, ty: int) -> Image:
        """Make one tile and cache it."""
        key = (level, tx, ty)
        if not self._tile_in_bounds(level, tx, ty):
            tile = _fill_tile()
        elif level == 0:
            tile = self._make_tile(tx, ty)
        else:
            native = self._native_tile(level, tx, ty)
            if native is not None:
                tile = native
            else:
                block = np.empty((2 * TILE_PX, 2 * TILE_PX, 4), dtype=np.uint8)
                for dy in (0, 1):
                    for dx in (0, 1):
                        block[
                            dy * TILE_PX : (dy + 1) * TILE_PX, dx * TILE_PX : (dx + 1) * TILE_PX
                        ] = self.tile(level - 1, 2 * tx + dx, 2 * ty + dy)
                tile = downsample2(block)
        tile.setflags(write=False)
        self._cache.put(key, tile)
        return tile

    def _tile_in_bounds(self, level: int, tx: int, ty: int) -> bool:
        w, h = self.level_size(level)
        if tx < 0 and w is not None:
            return False
        if ty < 0 and h is not None:
            return False
        if w is not None and tx * TILE_PX >= w:
            return False
        return not (h is not None and ty * TILE_PX >= h)

    def read_level(self, level: int, x0: int, y0: int, width: int, height: int) -> Image:
        """Pixels [y0, y0+height) x [x0, x0+width) of ``level``; FILL_BGRX outside the map."""
        if not 0 <= level < self.num_levels:
            msg = f"map {self.name}: pyramid level {level} outside 0..{self.num_levels - 1}"
            raise MapError(msg)
        out = np.empty((height, width, 4), dtype=np.uint8)
        paste_tiles(out, lambda tx, ty: self.tile(level, tx, ty), x0, y0)
        w, h = self.level_size(level)
        _fill_outside(out, x0, y0, w, h)
        return out

    def read_ground(
        self, x0_m: float, y0_m: float, x1_m: float, y1_m: float, gsd_m: float
    ) -> MapPatch:
        """Pixels covering the CRS rectangle (any corner order) at the level nearest gsd_m."""
        level = self.level_for_gsd(gsd_m)
        cols, rows = [], []
        for x, y in ((x0_m, y0_m), (x1_m, y1_m), (x0_m, y1_m), (x1_m, y0_m)):
            c, r = self.georef.crs_to_px(x, y)
            cols.append(c)
            rows.append(r)
        s = 1 << level
        off = (s - 1) / 2.0
        lx0 = math.floor((min(cols) - off) / s)
        ly0 = math.floor((min(rows) - off) / s)
        lx1 = math.ceil((max(cols) - off) / s)
        ly1 = math.ceil((max(rows) - off) / s)
        image = self.read_level(level, lx0, ly0, lx1 - lx0 + 1, ly1 - ly0 + 1)
        return MapPatch(image=image, level=level, x0_px=lx0, y0_px=ly0)

    @property
    def cache_bytes(self) -> int:
        """Bytes of tiles held in the cache now."""
        return self._cache.nbytes


def paste_tiles(
    out: npt.NDArray[Any], tile: Callable[[int, int], npt.NDArray[Any]], x0: int, y0: int
) -> None:
    """Fill ``out`` (one level's pixels from column ``x0``, row ``y0``) from ``tile(tx, ty)``,
    the TILE_PX-square tiles that cover it."""
    height, width = out.shape[:2]
    tx0, ty0 = x0 // TILE_PX, y0 // TILE_PX
    tx1, ty1 = (x0 + width - 1) // TILE_PX, (y0 + height - 1) // TILE_PX
    for ty in range(ty0, ty1 + 1):
        for tx in range(tx0, tx1 + 1):
            block = tile(tx, ty)
            ox, oy = tx * TILE_PX, ty * TILE_PX
            ax0, ay0 = max(x0, ox), max(y0, oy)
            ax1, ay1 = min(x0 + width, ox + TILE_PX), min(y0 + height, oy + TILE_PX)
            out[ay0 - y0 : ay1 - y0, ax0 - x0 : ax1 - x0] = block[
                ay0 - oy : ay1 - oy, ax0 - ox : ax1 - ox
            ]


def map_px_jacobian(
    source: MapSource, lat_deg: float, lon_deg: float
) -> tuple[float, float, float, float]:
    """d(level-0 map px)/d(north_m, east_m) at a point, row-major: (dx/dn, dx/de, dy/dn, dy/de).

    Central differences over 50 m each way: the map's scale and grid convergence at the point.
    """
    d = 50.0
    cols = []
    for dn, de in ((d, 0.0), (0.0, d)):
        la_p, lo_p, _ = ned2geodetic(dn, de, 0.0, lat_deg, lon_deg, 0.0)
        la_m, lo_m, _ = ned2geodetic(-dn, -de, 0.0, lat_deg, lon_deg, 0.0)
        xp, yp = source.latlon_to_map_px(la_p, lo_p)
        xm, ym = source.latlon_to_map_px(la_m, lo_m)
        cols.append(((xp - xm) / (2 * d), (yp - ym) / (2 * d)))
    return cols[0][0], cols[1][0], cols[0][1], cols[1][1]


def _fill_tile() -> Image:
    tile = np.empty((TILE_PX, TILE_PX, 4), dtype=np.uint8)
    tile[:] = FILL_BGRX
    return tile


def _fill_outside(out: Image, x0: int, y0: int, w: int | None, h: int | None) -> None:
    """Paint the part of ``out`` outside [0, w) x [0, h) with the fill colour."""
    height, width = out.shape[:2]
    if w is not None:
        left = min(width, max(0, -x0))
        right = min(width, max(0, x0 + width - w))
        if left:
            out[:, :left] = FILL_BGRX
        if right:
            out[:, width - right :] = FILL_BGRX
    if h is not None:
        top = min(height, max(0, -y0))
        bottom = min(height, max(0, y0 + height - h))
        if top:
            out[:top] = FILL_BGRX
        if bottom:
            out[height - bottom :] = FILL_BGRX


def map_error(source: str, what: str) -> MapError:
    """A one-line MapError naming the source."""
    return MapError(f"{source}: {what}")
