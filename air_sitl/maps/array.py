"""A map held in memory as one array (tests, small maps, images made by other code)."""

from __future__ import annotations

import math
from typing import Any

import cv2
import numpy as np

from air_sitl.maps.base import FILL_BGRX, TILE_PX, Georeference, Image, TiledMap, map_error
from air_sitl.maps.utm import UtmZone, latlon2utm


def utm_zone_of_crs(crs: str) -> UtmZone | None:
    """The zone of an ``EPSG:326zz``/``EPSG:327zz`` CRS string, else None."""
    text = crs.strip().upper()
    if not text.startswith("EPSG:"):
        return None
    try:
        code = int(text[5:])
    except ValueError:
        return None
    if 32601 <= code <= 32660:
        return UtmZone(code - 32600, True)
    if 32701 <= code <= 32760:
        return UtmZone(code - 32700, False)
    return None


def num_levels_for(width_px: int, height_px: int) -> int:
    """Levels until the whole map fits in one tile."""
    return 1 + max(0, math.ceil(math.log2(max(width_px, height_px, TILE_PX) / TILE_PX)))


class ArrayMap(TiledMap):
    """An in-memory BGR(x) image georeferenced in a UTM CRS (``EPSG:326zz`` or ``327zz``)."""

    def __init__(
        self,
        image: Image,
        *,
        crs: str,
        transform: tuple[float, float, float, float, float, float],
        ground_elevation_m: float,
        name: str = "array",
    ) -> None:
        super().__init__()
        zone = utm_zone_of_crs(crs)
        if zone is None:
            raise map_error(name, f"CRS {crs!r} is not a UTM EPSG code (EPSG:326zz/327zz)")
        if image.ndim != 3 or image.shape[2] not in (3, 4) or image.dtype != np.uint8:
            raise map_error(
                name, f"image of shape {image.shape} {image.dtype}: expected HxWx3 uint8"
            )
        self._zone = zone
        self._image = (
            cv2.cvtColor(image, cv2.COLOR_BGR2BGRA) if image.shape[2] == 3 else image.copy()
        )
        self._image[:, :, 3] = 255
        h, w = image.shape[:2]
        gsd = math.sqrt(abs(transform[1] * transform[5] - transform[2] * transform[4]))
        self.name = name
        self.georef = Georeference(crs=crs, transform=transform, width_px=w, height_px=h, gsd_m=gsd)
        self.ground_elevation_m = ground_elevation_m
        self.num_levels = num_levels_for(w, h)

    def _latlon_to_crs(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        return latlon2utm(lat_deg, lon_deg, self._zone)

    def _make_tile(self, tx: int, ty: int) -> Image:
        tile = np.empty((TILE_PX, TILE_PX, 4), dtype=np.uint8)
        tile[:] = FILL_BGRX
        x0, y0 = tx * TILE_PX, ty * TILE_PX
        part = self._image[y0 : y0 + TILE_PX, x0 : x0 + TILE_PX]
        tile[: part.shape[0], : part.shape[1]] = part
        return tile

    def describe(self) -> dict[str, Any]:
        """Provenance: an in-memory array."""
        h, w = self._image.shape[:2]
        return {"source": "array", "name": self.name, "size_px": [w, h], "crs": self.georef.crs}
