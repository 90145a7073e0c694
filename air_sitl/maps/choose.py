"""Choosing and opening the map and the surface model a flight's options name, and closing
them: the maps' end of a flight's set-up (builder, commands, sweep, recording), so that set-up
walks down to the maps without passing through the camera."""

from __future__ import annotations

from air_sitl.maps.base import MapSource
from air_sitl.maps.open import default_map_for_plan, open_map, open_surface
from air_sitl.maps.surface import SurfaceModel
from air_sitl.options import MapChoice
from air_sitl.state import GeoPoint


def open_chosen_map(choice: MapChoice, home: GeoPoint, plan_name: str = "") -> MapSource:
    """The MapSource ``choice`` names (default from the plan name: U* urban, F* forest,
    A* farmland)."""
    spec = choice.spec or default_map_for_plan(plan_name)
    return open_map(spec, home, seed=choice.seed, date=choice.date, shared_dir=choice.shared_dir)


def open_chosen_surface(choice: MapChoice, map_source: MapSource) -> SurfaceModel | None:
    """The surface ``choice.dem`` names over ``map_source`` (None: the flat ground)."""
    return open_surface(choice.dem, map_source)


def close_map(source: object) -> None:
    """Release a map's or a surface's files (GeoTIFFs hold some; procedural ones hold none)."""
    close = getattr(source, "close", None)
    if callable(close):
        close()
