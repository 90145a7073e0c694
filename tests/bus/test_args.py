"""Bus and GNSS-denial options: parsed once, refused with one line."""

from __future__ import annotations

import argparse
import json

import pytest

from air_sitl.bus.args import (
    add_bus_arguments,
    bus_config_from_args,
    bus_options_from_args,
    parse_wait_for,
)
from air_sitl.bus.session import DEFAULT_ENDPOINT, BusConfig, peer_listen_endpoints, zenoh_config
from air_sitl.cli import build_parser
from air_sitl.errors import OptionError
from air_sitl.options import add_gps_denial_arguments, gps_denied_from_args


def parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_bus_arguments(parser)
    add_gps_denial_arguments(parser)
    return parser.parse_args(list(argv))


def test_wait_for_name_and_lag() -> None:
    w = parse_wait_for("ex", 3.0)
    assert (w.name, w.max_lag, w.timeout_s) == ("ex", 1, 3.0)
    assert parse_wait_for("vo_1:4", 1.0).max_lag == 4
    for bad in ("ex:0", "ex:x", "a/b", ":2"):
        with pytest.raises(OptionError):
            parse_wait_for(bad, 1.0)


def test_gps_denial_windows_in_simulation_ns() -> None:
    args = parse("--gps-denied-window", "60:120", "--gps-denied-after", "300",
                 "--gps-denied-window", "1.5:2")  # fmt: skip
    assert gps_denied_from_args(args) == (
        (1_500_000_000, 2_000_000_000),
        (60_000_000_000, 120_000_000_000),
        (300_000_000_000, 2**62),
    )
    for bad in (("--gps-denied-window", "5"), ("--gps-denied-window", "5:4"),
                ("--gps-denied-after", "-1"), ("--gps-denied-window", "a:b")):  # fmt: skip
        with pytest.raises(OptionError, match="--gps-denied"):
            gps_denied_from_args(parse(*bad))


def test_any_bus_option_turns_publishing_on() -> None:
    assert not bus_options_from_args(parse()).enabled
    for argv in (["--zenoh"], ["--publish-truth"], ["--wait-for", "ex"], ["--svo-columns", "ex"],
                 ["--zenoh-listen", "tcp/127.0.0.1:7000"]):  # fmt: skip
        opts = bus_options_from_args(parse(*argv))
        assert opts.enabled and opts.publish, argv
    remote = bus_options_from_args(parse("--camera", "remote"))
    assert remote.enabled and remote.remote_camera and not remote.publish
    for bad in (["--imu-rate", "0"], ["--imu-rate", "400"], ["--wait-timeout", "-2"]):
        with pytest.raises(OptionError):
            bus_options_from_args(parse(*bad))


def test_default_endpoints_are_loopback_and_scouting_is_off() -> None:
    sim = zenoh_config(bus_config_from_args(parse(), serves=True))
    assert DEFAULT_ENDPOINT in sim.get_json("listen/endpoints")
    assert sim.get_json("connect/endpoints") == "[]"
    assert sim.get_json("scouting/multicast/enabled") == "false"
    client = zenoh_config(BusConfig())
    assert DEFAULT_ENDPOINT in client.get_json("connect/endpoints")
    # A connecting peer listens on an ephemeral loopback port: other peers behind the same
    # router reach it there (zenoh >= 1.9 routers no longer forward between peers).
    assert json.loads(client.get_json("listen/endpoints")) == ["tcp/127.0.0.1:0"]
    as_client = zenoh_config(BusConfig(mode="client"))
    assert as_client.get_json("listen/endpoints") == "[]"
    explicit = bus_config_from_args(parse("--zenoh-connect", "tcp/10.0.0.1:7447"), serves=True)
    assert explicit.listen == () and explicit.connect == ("tcp/10.0.0.1:7447",)
    chosen = bus_config_from_args(
        parse("--zenoh-connect", "tcp/127.0.0.1:7447", "--zenoh-listen", "tcp/127.0.0.1:7000"),
        serves=True,
    )
    assert json.loads(zenoh_config(chosen).get_json("listen/endpoints")) == ["tcp/127.0.0.1:7000"]
    with pytest.raises(OptionError, match="PROTOCOL/ADDRESS"):
        bus_config_from_args(parse("--zenoh-listen", "7447"), serves=True)
    with pytest.raises(OptionError, match="no such file"):
        bus_config_from_args(parse("--zenoh-config", "/nonexistent.json5"), serves=True)


def test_fly_takes_every_bus_option() -> None:
    args = build_parser().parse_args(
        ["fly", "p.plan", "--zenoh", "--zenoh-listen", "tcp/127.0.0.1:1", "--zenoh-connect",
         "tcp/127.0.0.1:2", "--zenoh-config", "z.json5", "--vehicle", "v", "--publish-truth",
         "--wait-for", "ex:2", "--wait-timeout", "3", "--svo-columns", "ex",
         "--gps-denied-after", "10", "--gps-denied-window", "1:2", "--camera", "remote"]
    )  # fmt: skip
    assert args.wait_for == "ex:2" and args.camera == "remote" and args.vehicle == "v"


def test_a_connecting_peer_listens_where_the_others_can_reach_it() -> None:
    assert peer_listen_endpoints(("tcp/127.0.0.1:7447", "tcp/localhost:7000")) == (
        "tcp/127.0.0.1:0",
    )
    assert peer_listen_endpoints(("tcp/[::1]:7447",)) == ("tcp/[::1]:0",)
    # Another protocol, or a host that does not resolve: nothing guessed.
    assert peer_listen_endpoints(("udp/127.0.0.1:7447", "tcp/no-such-host.invalid:7447")) == ()
    # A router on another host: this host's address on the way there, never 0.0.0.0.
    for endpoint in peer_listen_endpoints(("tcp/192.0.2.77:7447",)):
        assert endpoint.startswith("tcp/") and endpoint.endswith(":0")
        assert "0.0.0.0" not in endpoint
