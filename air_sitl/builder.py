"""One builder of a flight from its options: plan, home, map, camera, sensors, wind, denial.

The commands that fly (fly, serve, dataset) and the benchmarks parse their options at the edge
into a :class:`FlightSetup` (the plan loaded and validated once, here), then build what flies
from it: the map, the camera's FrameSource and the :class:`~air_sitl.runner.Flight` itself.
Recording it into an archive is :mod:`air_sitl.recording`'s part.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.mission.geometry import shift_altitudes
from air_sitl.mission.items import Mission
from air_sitl.mission.plan_file import load_mission
from air_sitl.options import FlightOptions, MapChoice
from air_sitl.runner import Flight, assemble_flight, home_of
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import GeoPoint

if TYPE_CHECKING:  # the camera and the maps load where they are used: not for --no-camera
    from air_sitl.camera.bridge import CameraBridge
    from air_sitl.camera.model import CameraModel
    from air_sitl.maps.base import MapSource
    from air_sitl.maps.surface import SurfaceModel


@dataclass(frozen=True, slots=True, kw_only=True)
class FlightSetup:
    """Everything one flight is built from, parsed and validated once.

    ``camera=None`` flies without rendering; ``render_workers=None`` takes one thread per core.
    ``plan`` is the file the mission came from (None for serve's uploaded missions).
    ``map_source``: a map already open (a sweep worker's, kept from flight to flight);
    None opens the one ``map`` chooses.
    """

    mission: Mission
    home: GeoPoint
    name: str  # scenario name: archive names, the default map (U* urban, F* forest, A* farmland)
    options: FlightOptions = field(default_factory=FlightOptions)
    plan: Path | None = None
    camera: CameraModel | None = None
    map: MapChoice = field(default_factory=MapChoice)
    render_workers: int | None = None
    map_source: MapSource | None = None


def load_setup(
    plan: Path,
    options: FlightOptions,
    *,
    camera: CameraModel | None = None,
    map: MapChoice | None = None,
    render_workers: int | None = None,
    name: str | None = None,
) -> FlightSetup:
    """Load and validate ``plan`` (PlanError naming the file and item); home is its home
    (with ``--dem``: on the ground there, :func:`home_on_terrain`).

    ``options.altitude_offset_m`` shifts the plan's altitudes (:func:`shift_altitudes`).
    """
    choice = map or MapChoice()
    mission = load_mission(plan, terrain=choice.dem is not None)
    setup = home_on_terrain(
        FlightSetup(
            mission=mission,
            home=home_of(mission),
            name=name or mission.name or plan.stem,
            options=options,
            plan=plan,
            camera=camera,
            map=choice,
            render_workers=render_workers,
        )
    )
    shifted = shift_altitudes(mission, options.altitude_offset_m, setup.home)
    return replace(setup, mission=shifted)


HOME_MISMATCH_M = 1.0  # a planned home this far from the DEM's ground is worth a warning


def home_on_terrain(setup: FlightSetup) -> FlightSetup:
    """``setup`` with home on the ground of its surface model (``--dem``); as it is without.

    As PX4 does, home is where the vehicle stands (PX4 sets it at arming from its position),
    not the plan's planned home altitude: the aircraft takes off from the terrain at home, and
    altitudes relative to home are above that ground. A planned home altitude more than
    HOME_MISMATCH_M away from it is said on stderr.
    """
    if setup.map.dem is None:
        return setup
    terrain, close = open_setup_terrain(setup)
    try:
        assert terrain is not None
        ground_m = terrain.terrain_at(setup.home.lat_deg, setup.home.lon_deg)
    finally:
        close()
    planned_m = setup.home.alt_amsl_m
    if abs(ground_m - planned_m) > HOME_MISMATCH_M:
        print(
            f"air-sitl: warning: {setup.mission.source}: home altitude {planned_m:.1f} m AMSL, "
            f"the ground there is at {ground_m:.1f} m (--dem {setup.map.dem}): the vehicle "
            "starts on the ground, and altitudes relative to home are above it",
            file=sys.stderr,
            flush=True,
        )
    return replace(setup, home=replace(setup.home, alt_amsl_m=ground_m))


def open_setup_terrain(setup: FlightSetup) -> tuple[SurfaceModel | None, Callable[[], None]]:
    """The surface model the flight meets (``--dem``; None without) and what closes its files.

    The flight opens its own (not the camera's): it samples level-0 cells along the track,
    the camera whole tiles at the level its altitude needs.
    """
    if setup.map.dem is None:
        return None, lambda: None
    from air_sitl.maps.choose import close_map, open_chosen_surface

    map_source = open_setup_map(setup)
    owned = setup.map_source is None  # a map handed in (a sweep worker's) stays open

    def close_map_source() -> None:
        if owned:
            close_map(map_source)

    try:
        surface = open_chosen_surface(setup.map, map_source)
    except BaseException:
        close_map_source()
        raise

    def close() -> None:
        close_map(surface)
        close_map_source()

    return surface, close


def open_setup_map(setup: FlightSetup) -> MapSource:
    """The map the camera sees (``--map`` default from the scenario name)."""
    if setup.map_source is not None:
        return setup.map_source
    from air_sitl.maps.choose import open_chosen_map

    return open_chosen_map(setup.map, setup.home, setup.name)


def open_camera(setup: FlightSetup, map_source: MapSource) -> CameraBridge:
    """The camera rendering ``map_source`` for ``setup`` (FrameSource; needs a camera model)."""
    assert setup.camera is not None, "open_camera: the setup flies without a camera"
    from air_sitl.camera.bridge import CameraBridge
    from air_sitl.camera.options import open_chosen_renderer

    renderer = open_chosen_renderer(setup.map, map_source, setup.camera, setup.options.seed)
    return CameraBridge(renderer, workers=setup.render_workers)


def build_flight(
    setup: FlightSetup,
    *,
    sinks: Sequence[Sink] = (),
    camera: FrameSource | None = None,
    auto_start: bool = True,
) -> Flight:
    """The Flight of ``setup``: flight model, autopilot, sensors (GNSS denial), sinks, camera.

    ``auto_start=False`` (serve): the vehicle waits on the ground, disarmed, for a client.
    """
    terrain, close_terrain = open_setup_terrain(setup)
    try:
        flight, _home, _initial = assemble_flight(
            setup.mission,
            setup.options,
            sinks=sinks,
            camera=camera,
            home=setup.home,
            auto_start=auto_start,
            terrain=terrain,
        )
    except BaseException:
        close_terrain()
        raise
    flight.on_close = (close_terrain,)
    return flight
