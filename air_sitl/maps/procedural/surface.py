"""The built-in surface models of the procedural maps (``--dem builtin``).

Terrain: gentle undulation for ``urban`` (a few metres over hundreds of metres), hills for
``forest`` (tens of metres over a kilometre); both pass through home's elevation at home, so
the plan's home altitude is the ground there. On top, the objects the texture draws at the
same date: roofs where houses are drawn, crowns where trees are, the forest canopy where the
texture shows forest. Heights at level L come from drawing at that level's resolution (the
texture's own coarse levels do the same), so a level's heights are area-like averages.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from air_sitl.maps.base import TILE_PX
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.farmland_layout import TERRAIN as FARM_TERRAIN
from air_sitl.maps.procedural.noise import fractal_noise, key_of
from air_sitl.maps.procedural.survey import acquire_heights
from air_sitl.maps.surface import BLOCK_PX, HeightBlock, Heights, TiledSurface

# (amplitude m, cell m, octaves) of the bare terrain of each map.
TERRAIN = {"urban": (4.0, 600.0, 2), "forest": (28.0, 900.0, 3), "farmland": FARM_TERRAIN}


class ProceduralSurface(TiledSurface):
    """Terrain plus roofs, crowns and canopy of one date of a procedural map."""

    def __init__(self, map_source: ProceduralMap) -> None:
        super().__init__(map_source)
        self.procedural = map_source
        self.name = f"builtin-{map_source.name}"
        self._terrain_block: HeightBlock | None = None
        # Bare terrain at home (level 0, bilinear over its cell) is home's elevation.
        hx, hy = self._home_px()
        ix, iy = math.floor(hx), math.floor(hy)
        ox, oy = map_source.origin_abs_px
        cell = HeightBlock(ix, iy, self._terrain(ox + ix, oy + iy, 2, map_source.georef.gsd_m))
        at_home = cell.at(hx, hy)
        assert at_home is not None
        self.offset_m = float(map_source.ground_elevation_m - at_home)

    def _home_px(self) -> tuple[float, float]:
        return self.procedural.home_px

    def _terrain(self, x0: int, y0: int, size: int, gsd_m: float) -> Heights:
        amp, cell_m, octaves = TERRAIN[self.procedural.kind]
        key = key_of(self.procedural.seed, 0x7E44)
        noise = fractal_noise(key, x0, y0, size, cell_m / gsd_m, octaves)
        return (amp * noise).astype(np.float32)

    def _make_tile(self, level: int, tx: int, ty: int) -> Heights:
        m = self.procedural
        ox, oy = m.origin_abs_px
        gsd = m.georef.gsd_m * (1 << level)
        x0 = (ox >> level) + tx * TILE_PX
        y0 = (oy >> level) + ty * TILE_PX
        ground = self._terrain(x0, y0, TILE_PX, gsd)
        objects = acquire_heights(m.world.objects, m.seed, x0, y0, TILE_PX, gsd, m.date)
        return ground + objects + np.float32(self.offset_m)

    def _bare_terrain_at_px(self, x: float, y: float) -> float:
        """The terrain's noise (no offset) at a continuous level-0 map pixel, bilinear; the
        last block is kept (a flight samples the ground at every physics step)."""
        block = self._terrain_block
        h = None if block is None else block.at(x, y)
        if h is None:
            x0, y0 = HeightBlock.origin(math.floor(x), math.floor(y))
            ox, oy = self.procedural.origin_abs_px
            t = self._terrain(ox + x0, oy + y0, BLOCK_PX, self.procedural.georef.gsd_m)
            block = self._terrain_block = HeightBlock(x0, y0, t)
            h = block.at(x, y)
            assert h is not None
        return h

    def terrain_at_map_px(self, x_px: float, y_px: float) -> float:
        """Bare terrain height (AMSL m) at a level-0 map pixel: where aircraft take off and land."""
        return self._bare_terrain_at_px(x_px, y_px) + self.offset_m

    def describe(self) -> dict[str, Any]:
        """Provenance: the built-in surface of a procedural map."""
        amp, cell_m, octaves = TERRAIN[self.procedural.kind]
        return {
            "source": "builtin",
            "map": self.procedural.name,
            "terrain_amplitude_m": amp,
            "terrain_cell_m": cell_m,
            "terrain_octaves": octaves,
            "offset_m": self.offset_m,
        }
