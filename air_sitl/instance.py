"""``serve --instance N``: vehicle N of a multi-vehicle session, numbered as PX4 SITL does.

Instance N is MAVLink system N+1; it sends to the ground station's port (14550, shared by every
vehicle: one QGroundControl sees them all) and to its own offboard/API port 14540+N (MAVSDK,
MAVROS: one per vehicle); its video goes to 5600+N, its zenoh keys live under ``air/uavN``, and
it stands :data:`HOME_SPACING_M` east of the previous one unless ``--home`` places it. The base
ports are options, so that tests and several sessions on one machine stay apart.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from air_sitl.errors import OptionError
from air_sitl.frames import ned2geodetic
from air_sitl.state import GeoPoint

GCS_PORT = 14550  # QGroundControl listens here
OFFBOARD_BASE_PORT = 14540  # MAVSDK / MAVROS of instance N at 14540+N
VIDEO_BASE_PORT = 5600  # QGroundControl's UDP video port; instance N streams to 5600+N
HOME_SPACING_M = 20.0  # east of the previous instance, as PX4's multi-vehicle script's row
MAX_INSTANCE = 253  # system ids 1..254 (255 is the ground station's)


@dataclass(frozen=True, slots=True, kw_only=True)
class Instance:
    """The identity and ports of one vehicle of a multi-vehicle session."""

    number: int = 0
    gcs_port: int = GCS_PORT
    offboard_base_port: int = OFFBOARD_BASE_PORT
    video_base_port: int = VIDEO_BASE_PORT

    @property
    def system_id(self) -> int:
        """MAV_SYS_ID: N+1."""
        return self.number + 1

    @property
    def links(self) -> tuple[str, str]:
        """The default ``--mavlink`` links: the shared ground station port, the own API port."""
        return (
            f"udpout:127.0.0.1:{self.gcs_port}",
            f"udpout:127.0.0.1:{self.offboard_base_port + self.number}",
        )

    @property
    def video_port(self) -> int:
        """The default video port: 5600+N."""
        return self.video_base_port + self.number

    @property
    def vehicle_name(self) -> str:
        """The zenoh vehicle name: ``uavN``."""
        return f"uav{self.number}"

    def home(self, home: GeoPoint) -> GeoPoint:
        """``home`` moved N * :data:`HOME_SPACING_M` east (instance 0 stays)."""
        if self.number == 0:
            return home
        lat, lon, alt = ned2geodetic(
            0.0, self.number * HOME_SPACING_M, 0.0, home.lat_deg, home.lon_deg, home.alt_amsl_m
        )
        return GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)


def add_instance_arguments(parser: argparse.ArgumentParser) -> None:
    """``--instance``, ``--gcs-port``, ``--offboard-base-port``, ``--video-base-port``."""
    g = parser.add_argument_group("several vehicles (as PX4 multi-vehicle SITL)")
    g.add_argument(
        "--instance",
        type=int,
        default=None,
        metavar="N",
        help="vehicle N of several: MAVLink system N+1, API port 14540+N, video port 5600+N, "
        f"zenoh vehicle uavN, home {HOME_SPACING_M:g} m east of vehicle N-1 (default: 0)",
    )
    g.add_argument(
        "--gcs-port",
        type=int,
        default=GCS_PORT,
        metavar="PORT",
        help=f"ground station port every instance sends to (default {GCS_PORT})",
    )
    g.add_argument(
        "--offboard-base-port",
        type=int,
        default=OFFBOARD_BASE_PORT,
        metavar="PORT",
        help=f"instance N's API/offboard port is PORT+N (default {OFFBOARD_BASE_PORT})",
    )
    g.add_argument(
        "--video-base-port",
        type=int,
        default=VIDEO_BASE_PORT,
        metavar="PORT",
        help=f"instance N's video port is PORT+N (default {VIDEO_BASE_PORT})",
    )


def instance_from_args(args: argparse.Namespace) -> Instance:
    """The instance the options describe (OptionError on a number or port out of range)."""
    number = 0 if args.instance is None else int(args.instance)
    if not 0 <= number <= MAX_INSTANCE:
        msg = f"--instance {number}: expected 0..{MAX_INSTANCE} (MAVLink system id N+1)"
        raise OptionError(msg)
    ports = {
        "--gcs-port": (int(args.gcs_port), 0),
        "--offboard-base-port": (int(args.offboard_base_port), number),
        "--video-base-port": (int(args.video_base_port), number),
    }
    for name, (port, offset) in ports.items():
        if not 1 <= port + offset <= 65535:
            msg = f"{name} {port}: with --instance {number} the port {port + offset} is not usable"
            raise OptionError(msg)
    return Instance(
        number=number,
        gcs_port=ports["--gcs-port"][0],
        offboard_base_port=ports["--offboard-base-port"][0],
        video_base_port=ports["--video-base-port"][0],
    )
