"""``air-sitl camera-bridge --map M``: render camera frames for simulators on the bus.

Two ways in (both served at once): ``fly --camera remote`` asks for each frame with a zenoh
query on ``air/<vehicle>/camera/render`` (lockstep, nothing lost, images byte-identical to the
in-process camera); and every ``truth`` sample that carries a frame index (a simulator with
``--publish-truth`` and no camera) is rendered and published on ``camera/image``. Rendering can
so run on another host. Runs until SIGINT or SIGTERM.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

from air_sitl.bus.args import add_connection_arguments, bus_config_from_args
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.remote_camera import CameraBridgeServer, RenderedFrame, RenderFn, RenderSettings
from air_sitl.bus.session import open_bus
from air_sitl.bus.signals import wait_until_signalled
from air_sitl.camera.info import camera_from_settings
from air_sitl.camera.options import (
    add_camera_arguments,
    add_map_arguments,
    camera_from_args,
    map_choice_from_args,
    open_chosen_renderer,
)
from air_sitl.errors import BusError
from air_sitl.maps.base import MapSource
from air_sitl.maps.choose import close_map, open_chosen_map
from air_sitl.options import MapChoice
from air_sitl.state import GeoPoint, VehicleState

HELP = "render camera frames for simulators over zenoh (fly --camera remote; truth -> camera/image)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``camera-bridge``."""
    add_map_arguments(parser)
    add_camera_arguments(parser)
    parser.add_argument(
        "--seed",
        type=int,
        default=0,
        help="noise seed of frames rendered from truth (render queries carry their own)",
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    add_connection_arguments(parser, serves=False)


def run(args: argparse.Namespace) -> int:
    """Serve renders until interrupted; exit 0 on SIGINT/SIGTERM."""
    keys = KeySpace(args.vehicle)
    camera = camera_from_args(args)  # validates the options before joining the bus
    spec = args.map or "urban"
    choice = replace(map_choice_from_args(args), spec=spec)
    maps: list[MapSource] = []

    def factory(settings: RenderSettings) -> RenderFn:
        return _renderer(choice, settings, maps)

    def free_settings(home: GeoPoint) -> RenderSettings:
        return RenderSettings(home=home, camera=camera.settings(), seed=args.seed)

    with open_bus(bus_config_from_args(args, serves=False)) as bus:
        server = CameraBridgeServer(bus, keys, factory, free_settings=free_settings)
        if not args.quiet:
            print(
                f"air-sitl camera-bridge: map {spec}; serving {keys.render}, "
                f"{keys.truth} -> {keys.image}",
                flush=True,
            )
        wait_until_signalled()
        if not args.quiet:
            print(
                f"air-sitl camera-bridge: stopped; {server.rendered} frames rendered, "
                f"{server.published} published from truth",
                flush=True,
            )
    for source in maps:
        close_map(source)
    return 0


def _renderer(choice: MapChoice, settings: RenderSettings, maps: list[MapSource]) -> RenderFn:
    """A render function for one (home, camera, seed): the in-process camera's Renderer."""
    try:
        camera = camera_from_settings(settings.camera)
    except (KeyError, TypeError, ValueError, IndexError) as err:
        msg = f"camera/render: bad camera settings ({err!r})"
        raise BusError(msg) from None
    map_source = open_chosen_map(choice, settings.home)
    maps.append(map_source)
    renderer = open_chosen_renderer(choice, map_source, camera, settings.seed)

    def render(state: VehicleState, index: int) -> RenderedFrame:
        jpeg, xy = renderer.frame_jpeg(state, index)
        # nodata_fraction is per thread: that of the frame just rendered on this one.
        return RenderedFrame(
            jpeg, xy, camera.width_px, camera.height_px, renderer.nodata_fraction()
        )

    return render
