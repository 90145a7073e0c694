"""The options of every command that flies a vehicle (``fly``, ``serve``), in help order."""

from __future__ import annotations

import argparse

from air_sitl.bus.args import add_bus_arguments
from air_sitl.camera.options import add_camera_arguments, add_map_arguments
from air_sitl.options import add_flight_arguments, add_gps_denial_arguments


def add_vehicle_arguments(parser: argparse.ArgumentParser, *, default_speed: float) -> None:
    """Flight, map, camera, zenoh bus and GNSS denial options."""
    add_flight_arguments(parser, default_speed=default_speed)
    add_map_arguments(parser)
    add_camera_arguments(parser)
    add_bus_arguments(parser)
    add_gps_denial_arguments(parser)
