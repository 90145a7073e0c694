"""Map sources: GeoTIFF/COG files and procedural ``urban``/``forest``/``farmland`` worlds,
by pyramid level."""

from __future__ import annotations

from air_sitl.maps.base import FILL_BGRX, TILE_PX, Georeference, MapPatch, MapSource
from air_sitl.maps.open import default_map_for_plan, open_map

__all__ = [
    "FILL_BGRX",
    "TILE_PX",
    "Georeference",
    "MapPatch",
    "MapSource",
    "default_map_for_plan",
    "open_map",
]
