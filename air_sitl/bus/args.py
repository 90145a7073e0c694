"""Command-line options of the bus (fly, serve, bridges): parsed here once."""

from __future__ import annotations

import argparse
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.bus.defaults import DEFAULT_ENDPOINT, DEFAULT_MAX_NAMES
from air_sitl.bus.keys import DEFAULT_VEHICLE, KeySpace, check_chunk
from air_sitl.bus.ros2.options import Ros2Options, add_ros2_arguments, ros2_options_from_args
from air_sitl.errors import OptionError
from air_sitl.options import int_in_range, positive_number

if TYPE_CHECKING:  # zenoh loads when a command opens the bus, not for its --help
    from air_sitl.bus.lockstep import WaitFor
    from air_sitl.bus.session import BusConfig, Mode

DEFAULT_WAIT_TIMEOUT_S = 10.0


def add_connection_arguments(parser: argparse.ArgumentParser, *, serves: bool) -> None:
    """``--zenoh-listen``, ``--zenoh-connect``, ``--zenoh-config``, ``--zenoh-mode``, ``--vehicle``.

    ``serves``: the program listens by default (a simulator), else it connects.
    """
    g = parser.add_argument_group("zenoh connection")
    default = DEFAULT_ENDPOINT if serves else f"none, connect to {DEFAULT_ENDPOINT}"
    g.add_argument(
        "--zenoh-listen",
        action="append",
        metavar="ENDPOINT",
        help=f"listen on this zenoh endpoint, repeatable (default: {default})",
    )
    g.add_argument(
        "--zenoh-connect",
        action="append",
        metavar="ENDPOINT",
        help="connect to this zenoh endpoint (a router or a peer), repeatable",
    )
    g.add_argument(
        "--zenoh-config",
        default=None,
        metavar="FILE",
        help="zenoh JSON5 config (TLS, access control ...); the options above apply on top",
    )
    g.add_argument(
        "--zenoh-mode",
        choices=("peer", "client"),
        default="peer",
        help="zenoh session mode (default peer; multicast scouting is off)",
    )
    g.add_argument(
        "--vehicle",
        default=DEFAULT_VEHICLE,
        metavar="NAME",
        help=f"vehicle name in the key space air/<NAME>/... (default {DEFAULT_VEHICLE})",
    )


def add_bus_arguments(parser: argparse.ArgumentParser) -> None:
    """Every bus option of a command that flies a vehicle (fly, serve)."""
    g = parser.add_argument_group("zenoh bus")
    g.add_argument(
        "--zenoh",
        action="store_true",
        help="publish camera frames, IMU, GNSS, clock and mission status on zenoh",
    )
    g.add_argument(
        "--publish-truth",
        action="store_true",
        help="also publish ground truth on air/<vehicle>/truth (implies --zenoh)",
    )
    g.add_argument(
        "--imu-rate",
        default="200",
        metavar="HZ",
        help="rate of air/<vehicle>/imu (default 200, the physics rate)",
    )
    g.add_argument(
        "--wait-for",
        default=None,
        metavar="NAME[:MAX_LAG]",
        help="lockstep with the estimator NAME: frame k+MAX_LAG (default 1) is not rendered "
        "before its estimate of frame k arrived (implies --zenoh)",
    )
    g.add_argument(
        "--wait-timeout",
        default=str(DEFAULT_WAIT_TIMEOUT_S),
        metavar="S",
        help="wall seconds to wait for an estimator or the remote camera before giving up "
        f"(default {DEFAULT_WAIT_TIMEOUT_S:g})",
    )
    g.add_argument(
        "--svo-columns",
        default=None,
        metavar="NAME",
        help="fill AIR's SvoX/SvoY/SvoZ with the positions the estimator NAME sent (ENU, home)",
    )
    g.add_argument(
        "--max-estimate-names",
        default=str(DEFAULT_MAX_NAMES),
        metavar="N",
        help="estimators (estimate/<name> keys) one flight logs; estimates under further names "
        f"are rejected and counted (default {DEFAULT_MAX_NAMES})",
    )
    g.add_argument(
        "--camera",
        choices=("local", "remote"),
        default="local",
        help="render in this process (local, default) or ask `air-sitl camera-bridge` over zenoh",
    )
    add_ros2_arguments(parser)
    add_connection_arguments(parser, serves=True)


@dataclass(frozen=True, slots=True, kw_only=True)
class BusOptions:
    """The bus options of one flying command, validated."""

    enabled: bool  # open a session at all
    publish: bool  # put the simulation on the bus
    config: BusConfig
    keys: KeySpace
    publish_truth: bool
    imu_rate_hz: float
    wait: WaitFor | None
    wait_timeout_s: float
    svo_columns: str | None
    remote_camera: bool
    max_estimate_names: int = DEFAULT_MAX_NAMES
    expected: tuple[str, ...] = ()  # estimators the flight relies on (wait-for, svo, nav-aid)
    ros2: Ros2Options | None = None  # --ros2: the ROS 2 view beside our keys


def bus_config_from_args(args: argparse.Namespace, *, serves: bool) -> BusConfig:
    """The session configuration of the connection options."""
    from air_sitl.bus.session import BusConfig

    config_file = None
    if args.zenoh_config:
        config_file = Path(args.zenoh_config)
        if not config_file.is_file():
            msg = f"--zenoh-config {config_file}: no such file"
            raise OptionError(msg)
    listen = tuple(args.zenoh_listen) if args.zenoh_listen else None
    connect = tuple(args.zenoh_connect) if args.zenoh_connect else None
    for endpoint in (*(listen or ()), *(connect or ())):
        if "/" not in endpoint:
            msg = f"zenoh endpoint {endpoint!r}: expected PROTOCOL/ADDRESS, e.g. {DEFAULT_ENDPOINT}"
            raise OptionError(msg)
    if listen is None and connect is not None:
        listen = ()
    if connect is None and listen is not None:
        connect = ()
    mode: Mode = "client" if getattr(args, "zenoh_mode", "peer") == "client" else "peer"
    return BusConfig(
        mode=mode, listen=listen, connect=connect, config_file=config_file, serves=serves
    )


def ros2_config(config: BusConfig) -> BusConfig:
    """The session of a ROS 2 view: timestamped (transient-local caches need it). A peer that
    only connects listens on a free port as rmw_zenoh's sessions do (the session's own rule,
    :func:`air_sitl.bus.session.peer_listen_endpoints`), so ROS 2 nodes reach it directly."""
    return replace(config, timestamping=True)


def parse_wait_for(text: str, timeout_s: float) -> WaitFor:
    """``NAME`` or ``NAME:MAX_LAG`` (MAX_LAG an integer >= 1)."""
    from air_sitl.bus.lockstep import WaitFor

    name, _, lag_text = text.partition(":")
    check_chunk("--wait-for", name)
    lag = 1
    if lag_text:
        try:
            lag = int(lag_text)
        except ValueError:
            lag = 0
        if lag < 1:
            msg = f"--wait-for {text!r}: MAX_LAG must be an integer >= 1"
            raise OptionError(msg)
    return WaitFor(name=name, max_lag=lag, timeout_s=timeout_s)


def bus_options_from_args(args: argparse.Namespace) -> BusOptions:
    """Validate the bus options of ``fly``/``serve``."""
    timeout = positive_number("--wait-timeout", args.wait_timeout)
    imu_rate = positive_number("--imu-rate", args.imu_rate)
    if imu_rate > 200:
        msg = f"--imu-rate {args.imu_rate}: at most 200 Hz (the physics rate)"
        raise OptionError(msg)
    wait = parse_wait_for(args.wait_for, timeout) if args.wait_for else None
    svo = check_chunk("--svo-columns", args.svo_columns) if args.svo_columns else None
    remote = args.camera == "remote"
    max_names = int_in_range("--max-estimate-names", args.max_estimate_names, 1, 100_000)
    explicit = bool(args.zenoh_listen or args.zenoh_connect or args.zenoh_config)
    aid = getattr(args, "nav_aid", None)
    zenoh_aid = aid is not None and aid != "mavlink"  # --nav-aid NAME implies --zenoh
    ros2 = ros2_options_from_args(args)
    publish = bool(args.zenoh or args.publish_truth or wait or svo or zenoh_aid or ros2)
    config = bus_config_from_args(args, serves=True)
    named = (wait.name if wait else None, svo, aid if zenoh_aid else None)
    expected = tuple(dict.fromkeys(n for n in named if n))
    return BusOptions(
        enabled=publish or remote or explicit,
        publish=publish or explicit,
        config=config if ros2 is None else ros2_config(config),
        keys=KeySpace(args.vehicle),
        publish_truth=bool(args.publish_truth),
        imu_rate_hz=imu_rate,
        wait=wait,
        wait_timeout_s=timeout,
        svo_columns=svo,
        remote_camera=remote,
        max_estimate_names=max_names,
        expected=expected,
        ros2=ros2,
    )
