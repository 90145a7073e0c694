"""``air-sitl camera-bridge --map M``: render camera frames for simulators on the bus.

Two ways in (both served at once): ``fly --camera remote`` asks for each frame with a zenoh
query on ``air/<vehicle>/camera/render`` (lockstep, nothing lost, images byte-identical to the
in-process camera); and every ``truth`` sample that carries a frame index (a simulator with
``--publish-truth`` and no camera) is rendered and published on ``camera/image``. Rendering can
so run on another host. Runs until SIGINT or SIGTERM.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

from air_sitl.bus.args import add_connection_arguments, bus_config_from_args, ros2_config
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.ros2.options import Ros2Options, add_ros2_arguments, ros2_options_from_args
from air_sitl.camera.options import (
    add_camera_arguments,
    add_map_arguments,
    camera_from_args,
    map_choice_from_args,
    open_chosen_renderer,
)
from air_sitl.errors import BusError
from air_sitl.foxglove.commands import add_live_arguments, open_live
from air_sitl.options import MapChoice
from air_sitl.state import GeoPoint, VehicleState

if TYPE_CHECKING:  # zenoh and the renderer load when the bridge runs, not for --help
    from air_sitl.bus.remote_camera import RenderFn, RenderSettings
    from air_sitl.bus.ros2.view import Ros2Camera
    from air_sitl.bus.session import Bus
    from air_sitl.camera.model import CameraModel
    from air_sitl.maps.base import MapSource

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
    add_ros2_arguments(parser)
    add_live_arguments(parser)
    add_connection_arguments(parser, serves=False)


def run(args: argparse.Namespace) -> int:
    """Serve renders until interrupted; exit 0 on SIGINT/SIGTERM."""
    from air_sitl.bus.remote_camera import CameraBridgeServer, RenderSettings
    from air_sitl.bus.session import open_bus
    from air_sitl.bus.signals import wait_until_signalled
    from air_sitl.maps.choose import close_map

    keys = KeySpace(args.vehicle)
    camera = camera_from_args(args)  # validates the options before joining the bus
    ros2 = ros2_options_from_args(args)
    config = bus_config_from_args(args, serves=False)
    spec = args.map or "urban"
    choice = replace(map_choice_from_args(args), spec=spec)
    maps: list[MapSource] = []

    def factory(settings: RenderSettings) -> RenderFn:
        return _renderer(choice, settings, maps)

    def free_settings(home: GeoPoint) -> RenderSettings:
        return RenderSettings(home=home, camera=camera.settings(), seed=args.seed)

    live = open_live(args, vehicle=args.vehicle, home=None, camera=camera)
    with open_bus(config if ros2 is None else ros2_config(config)) as bus:
        on_published: Callable[[int, int, bytes], None] | None = None
        if ros2 is not None:
            on_published = _ros2_camera(bus, ros2, keys, camera).publish
        if live is not None:
            on_published = _also_to(live.on_image, on_published)
        server = CameraBridgeServer(
            bus, keys, factory, free_settings=free_settings, on_published=on_published
        )
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
    if live is not None:
        live.close()
    for source in maps:
        close_map(source)
    return 0


def _also_to(
    on_image: Callable[[int, bytes], None], then: Callable[[int, int, bytes], None] | None
) -> Callable[[int, int, bytes], None]:
    """A frame published from truth goes to the Foxglove view, then to ``then``."""

    def publish(index: int, sim_time_ns: int, jpeg: bytes) -> None:
        on_image(sim_time_ns, jpeg)
        if then is not None:
            then(index, sim_time_ns, jpeg)

    return publish


def _ros2_camera(bus: Bus, ros2: Ros2Options, keys: KeySpace, camera: CameraModel) -> Ros2Camera:
    """``--ros2``: node ``air_sitl_<vehicle>_camera`` with the camera's ROS 2 topics (frames
    rendered from truth; a ``fly --ros2`` of the same vehicle publishes its own)."""
    from air_sitl.bus.ros2.view import Ros2Camera, open_node

    node = open_node(bus, ros2, keys, suffix="_camera")
    return Ros2Camera(node, keys, camera)


def _renderer(choice: MapChoice, settings: RenderSettings, maps: list[MapSource]) -> RenderFn:
    """A render function for one (home, camera, seed): the in-process camera's Renderer."""
    from air_sitl.bus.remote_camera import RenderedFrame
    from air_sitl.camera.info import camera_from_settings
    from air_sitl.maps.choose import open_chosen_map

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
