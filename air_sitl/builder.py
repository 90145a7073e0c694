"""One builder of a flight from its options: plan, home, map, camera, sensors, wind, denial.

The commands that fly (fly, serve, dataset) and the benchmarks parse their options at the edge
into a :class:`FlightSetup` (the plan loaded and validated once, here), then build what flies
from it: the map, the camera's FrameSource and the :class:`~air_sitl.runner.Flight` itself.
Recording it into an archive is :mod:`air_sitl.recording`'s part.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from air_sitl.camera.bridge import CameraBridge
from air_sitl.camera.model import CameraModel
from air_sitl.camera.options import open_chosen_map, open_chosen_surface
from air_sitl.camera.render import Renderer
from air_sitl.errors import OptionError
from air_sitl.maps.base import MapSource
from air_sitl.mission.items import (
    LOITER_COMMANDS,
    WAYPOINT_COMMANDS,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
)
from air_sitl.mission.plan_file import load_mission
from air_sitl.options import FlightOptions, MapChoice
from air_sitl.runner import Flight, assemble_flight, home_of
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import GeoPoint


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
    name: str  # scenario name: archive names, the default map (U* urban, F* forest)
    options: FlightOptions = field(default_factory=FlightOptions)
    plan: Path | None = None
    camera: CameraModel | None = None
    map: MapChoice = field(default_factory=MapChoice)
    render_workers: int | None = None
    map_source: MapSource | None = None


# Items whose altitude is a height to fly at; RTL and landing keep theirs.
_SHIFTED_COMMANDS = frozenset({MavCmd.NAV_TAKEOFF, *WAYPOINT_COMMANDS, *LOITER_COMMANDS})
_RELATIVE_FRAMES = frozenset({MavFrame.GLOBAL_RELATIVE_ALT, MavFrame.GLOBAL_RELATIVE_ALT_INT})


def shift_altitudes(mission: Mission, offset_m: float, home: GeoPoint) -> Mission:
    """``mission`` with every altitude it flies at (take-off, waypoints, loiters, rally points)
    raised by ``offset_m``; the capture items and their window stay as they are.

    OptionError when a shifted altitude is not above home.
    """
    if offset_m == 0.0:
        return mission

    def shifted(item: MissionItem, index: int, kind: str) -> MissionItem:
        alt_m = item.alt_m + offset_m
        above_home_m = alt_m if item.frame in _RELATIVE_FRAMES else alt_m - home.alt_amsl_m
        if above_home_m <= 0.0:
            msg = (
                f"--altitude-offset {offset_m:g}: {mission.source}: {kind} {index}: altitude "
                f"{item.alt_m:g} m would be {above_home_m:g} m above home (must stay above it)"
            )
            raise OptionError(msg)
        return replace(item, alt_m=alt_m)

    items = tuple(
        shifted(item, i, "item") if item.command in _SHIFTED_COMMANDS else item
        for i, item in enumerate(mission.items)
    )
    rally = tuple(shifted(item, i, "rally point") for i, item in enumerate(mission.rally))
    return replace(mission, items=items, rally=rally)


def load_setup(
    plan: Path,
    options: FlightOptions,
    *,
    camera: CameraModel | None = None,
    map: MapChoice | None = None,
    render_workers: int | None = None,
    name: str | None = None,
) -> FlightSetup:
    """Load and validate ``plan`` (PlanError naming the file and item); home is its home.

    ``options.altitude_offset_m`` shifts the plan's altitudes (:func:`shift_altitudes`).
    """
    mission = load_mission(plan)
    home = home_of(mission)
    mission = shift_altitudes(mission, options.altitude_offset_m, home)
    return FlightSetup(
        mission=mission,
        home=home,
        name=name or mission.name or plan.stem,
        options=options,
        plan=plan,
        camera=camera,
        map=map or MapChoice(),
        render_workers=render_workers,
    )


def open_setup_map(setup: FlightSetup) -> MapSource:
    """The map the camera sees (``--map`` default from the scenario name)."""
    if setup.map_source is not None:
        return setup.map_source
    return open_chosen_map(setup.map, setup.home, setup.name)


def open_camera(setup: FlightSetup, map_source: MapSource) -> CameraBridge:
    """The camera rendering ``map_source`` for ``setup`` (FrameSource; needs a camera model)."""
    assert setup.camera is not None, "open_camera: the setup flies without a camera"
    renderer = Renderer(
        map_source,
        setup.camera,
        seed=setup.options.seed,
        surface=open_chosen_surface(setup.map, map_source),
    )
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
    flight, _home, _initial = assemble_flight(
        setup.mission,
        setup.options,
        sinks=sinks,
        camera=camera,
        home=setup.home,
        auto_start=auto_start,
    )
    return flight
