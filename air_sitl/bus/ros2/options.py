"""``--ros2``, ``--ros-domain-id``, ``--ros-namespace``, ``--ros-distro``: parsed here once."""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from air_sitl.bus.ros2.layout import ros_name_token
from air_sitl.errors import OptionError

MAX_DOMAIN_ID = 232  # the largest ROS_DOMAIN_ID ROS 2 allows
DISTRO_NAMES = ("jazzy", "kilted", "lyrical")  # each has a rosbags store ROS2_<NAME>
DEFAULT_DISTRO = "kilted"


@dataclass(frozen=True, slots=True, kw_only=True)
class Ros2Options:
    """``--ros-domain-id``, ``--ros-namespace``, ``--ros-distro``."""

    domain_id: int = 0
    namespace: str = "/"  # absolute, no trailing '/', '/' for none
    distro: str = DEFAULT_DISTRO

    def resolve(self, name: str) -> str:
        """A relative topic name in the node's namespace (``air/uav0/imu`` -> ``/air/uav0/imu``)."""
        return f"{self.namespace.rstrip('/')}/{name}"


def add_ros2_arguments(parser: argparse.ArgumentParser) -> None:
    """The ROS 2 options of a command that joins the bus."""
    g = parser.add_argument_group("ROS 2 (rmw_zenoh layout, no ROS 2 install needed)")
    g.add_argument(
        "--ros2",
        action="store_true",
        help="also be the ROS 2 node air_sitl_<vehicle>: publish camera, IMU, GNSS, clock and "
        "TF as rmw_zenoh does, take estimates on /air/<vehicle>/estimates/<name> "
        "(implies --zenoh)",
    )
    g.add_argument(
        "--ros-domain-id",
        default="0",
        metavar="N",
        help=f"ROS domain id, as ROS_DOMAIN_ID (0..{MAX_DOMAIN_ID}, default 0)",
    )
    g.add_argument(
        "--ros-namespace",
        default="/",
        metavar="NS",
        help="namespace of the node and its air/... topics (default /; /clock and /tf_static "
        "stay global)",
    )
    g.add_argument(
        "--ros-distro",
        choices=DISTRO_NAMES,
        default=DEFAULT_DISTRO,
        help=f"message definitions and type hashes of this distro (default {DEFAULT_DISTRO})",
    )


def ros2_options_from_args(args: argparse.Namespace) -> Ros2Options | None:
    """The validated ROS 2 options; None without ``--ros2``."""
    if not getattr(args, "ros2", False):
        return None
    text = str(args.ros_domain_id)
    try:
        domain = int(text)
    except ValueError:
        domain = -1
    if not 0 <= domain <= MAX_DOMAIN_ID:
        msg = f"--ros-domain-id {text}: expected an integer 0..{MAX_DOMAIN_ID}"
        raise OptionError(msg)
    parts = [p for p in str(args.ros_namespace).split("/") if p]
    for part in parts:
        ros_name_token(f"--ros-namespace {args.ros_namespace}", part)
    namespace = "/" + "/".join(parts)
    vehicle = getattr(args, "vehicle", None)
    if vehicle is not None:  # it names the node and the topics
        ros_name_token("--vehicle (with --ros2)", vehicle)
    return Ros2Options(domain_id=domain, namespace=namespace, distro=args.ros_distro)
