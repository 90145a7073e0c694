"""Every documented bus topology routes, with real processes (docs/bus-topologies.md).

Peers through a router, clients through a router, peer to peer, and the docker-compose.yml
services run by hand (a router, ``serve`` and the example localizer with the compose file's
own arguments; only the endpoints are this machine's). zenoh >= 1.9 routers do not forward
between two peers: the peers must reach each other, which they do because a connecting peer
listens on an ephemeral port (air_sitl/bus/session.py).
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml
from ports import free_port
from pymavlink import mavutil
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, Message, open_bus
from air_sitl.mission.plan_file import load_mission
from tests.mavlink.gcs import Gcs

from .helpers import (
    HOME,
    REPO,
    SAFETY_S,
    WAIT_SAFETY,
    cli,
    free_endpoint,
    start,
    stop,
    wait_for_line,
    wait_until,
)

pytestmark = pytest.mark.integration

KEYS = KeySpace("uav0")
AGAIN_AFTER_S = 120.0  # wall seconds without the estimates before the mission is flown again
M = mavutil.mavlink


def router(endpoint: str) -> subprocess.Popen[str]:
    proc = start(cli("router", "--listen", endpoint))
    wait_for_line(proc, "listening on")
    return proc


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_short_plan(tmp_path_factory.mktemp("plan") / "UB.plan", HOME, leg_m=40.0)


def fly_beside_deadreckon(
    plan: Path, out: Path, fly_net: list[str], loc_net: list[str]
) -> dict[str, object]:
    """``localize --bus --method deadreckon --name dr`` and ``fly --wait-for dr`` (lockstep:
    the flight waits for the localizer to subscribe, so none of its frames is missed); the
    flight's summary.json."""
    loc = start(
        cli("localize", "--bus", "--method", "deadreckon", "--name", "dr", "--wait", "120",
            *loc_net)
    )  # fmt: skip
    try:
        flown = subprocess.run(
            cli("fly", str(plan), "--air-start", "--quiet", "--out", str(out), "--wait-for",
                "dr", *WAIT_SAFETY, *fly_net, *SMALL_CAMERA),
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
        # The localizer leaves by itself once the capture window is over (a signal then could
        # land while it restores its handlers).
        with contextlib.suppress(subprocess.TimeoutExpired):
            loc.wait(timeout=60)
    finally:
        code, _, loc_err = stop(loc)
    assert flown.returncode == 0, flown.stderr
    assert code == 0, loc_err
    assert "no estimate from" not in flown.stderr
    summary: dict[str, object] = json.loads((out / "summary.json").read_text())
    return summary


@pytest.mark.parametrize("mode", ["peer", "client"])
def test_fly_and_a_localizer_through_a_router(plan: Path, tmp_path: Path, mode: str) -> None:
    endpoint = free_endpoint()
    hub = router(endpoint)
    try:
        net = ["--zenoh-connect", endpoint, "--zenoh-mode", mode]
        summary = fly_beside_deadreckon(plan, tmp_path / "out", net, net)
    finally:
        code, _, err = stop(hub)
    assert code == 0, err
    frames = summary["frames_published"]
    assert isinstance(frames, int) and frames > 100
    assert summary["estimates"] == {"dr": frames}
    assert summary["frames_without_estimate"] == {"dr": 0}


def test_peer_to_peer_without_a_router(plan: Path, tmp_path: Path) -> None:
    endpoint = free_endpoint()
    summary = fly_beside_deadreckon(
        plan, tmp_path / "out", ["--zenoh-listen", endpoint], ["--zenoh-connect", endpoint]
    )
    assert summary["estimates"] == {"dr": summary["frames_published"]}


def test_two_bare_peers_hear_each_other_through_a_router() -> None:
    """The issue's reduction: two peers connected only to the router, 50 samples."""
    endpoint = free_endpoint()
    hub = router(endpoint)
    try:
        a = open_bus(BusConfig(connect=(endpoint,)))
        b = open_bus(BusConfig(connect=(endpoint,)))
        got: list[bytes] = []
        with a, b:
            b.subscribe("t/x", lambda m: got.append(m.payload))
            pub = a.publisher("t/x", encoding="text/plain", block=True)
            assert wait_until(lambda: pub.matched)
            for i in range(50):
                pub.put(str(i).encode())
            assert wait_until(lambda: len(got) == 50)
        assert got == [str(i).encode() for i in range(50)]
    finally:
        stop(hub)


def lan_address() -> str:
    """A non-loopback address of this host (a container network's stand-in), or skip."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect(("203.0.113.1", 9))  # TEST-NET-3: only picks a route
        except OSError:
            pytest.skip("no non-loopback IPv4 route on this host")
        address = str(probe.getsockname()[0])
    if ipaddress.ip_address(address).is_loopback:
        pytest.skip("no non-loopback IPv4 address on this host")
    return address


def compose_command(service: str, swap: dict[str, str]) -> list[str]:
    compose = yaml.safe_load((REPO / "docker-compose.yml").read_text())
    argv = [str(a) for a in compose["services"][service]["command"]]
    return [swap.get(a, a) for a in argv]


def test_the_compose_services_by_hand(tmp_path: Path) -> None:
    """docker-compose.yml's router, simulator and localizer, each with its own arguments
    (endpoints on this host's network address instead of the compose network, a free MAVLink
    port, the simulator unpaced, UC-200 as a short plan from its home: its capture window
    comes after seconds, not after 250 simulated seconds of video): a ground station flies
    the mission and a third program, a peer on the router, hears the example localizer's
    estimates."""
    uc200 = load_mission(REPO / "missions" / "UC-200.plan").planned_home
    assert uc200 is not None
    short = write_short_plan(tmp_path / "UC-200.plan", uc200, leg_m=150.0, alt_m=80.0)
    address = lan_address()
    port = free_port()
    mav = free_port()
    # The video goes to the host's QGroundControl (host.docker.internal in the container):
    # here a socket of this test's, so that sending never errs.
    viewer = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    viewer.bind(("127.0.0.1", 0))
    swap = {
        "tcp/0.0.0.0:7447": f"tcp/{address}:{port}",
        "tcp/router:7447": f"tcp/{address}:{port}",
        "tcpin:0.0.0.0:5760": f"tcpin:127.0.0.1:{mav}",
        "udp://host.docker.internal:5600": f"udp://127.0.0.1:{viewer.getsockname()[1]}",
        "1": "0",  # --speed 1 -> 0: as fast as the machine goes
        "missions/UC-200.plan": str(short),
    }
    hub_cmd = compose_command("router", swap)
    sim_cmd = compose_command("simulator", swap)
    loc_cmd = compose_command("localizer", swap)
    assert hub_cmd[0] == sim_cmd[0] == "air-sitl" and loc_cmd[0] == "python"
    heard: list[Message] = []
    reached = False
    hub = start(cli(*hub_cmd[1:]), cwd=REPO)
    procs = [hub]
    try:
        wait_for_line(hub, "listening on")
        sim = start(cli(*sim_cmd[1:]), cwd=REPO)
        procs.append(sim)
        wait_for_line(sim, "vehicle ready")
        loc = start([sys.executable, *loc_cmd[1:]], cwd=REPO)
        procs.append(loc)
        wait_for_line(loc, "publishing on")
        lock = threading.Lock()

        def on_estimate(message: Message) -> None:
            with lock:
                heard.append(message)

        observer = open_bus(BusConfig(connect=(f"tcp/{address}:{port}",)))
        with observer:
            observer.subscribe(KEYS.estimate("example"), on_estimate)
            gcs = Gcs(f"tcp:127.0.0.1:{mav}")
            try:
                gcs.connect()
                assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
                # Unpaced, the capture leg may be flown before the localizer's subscription
                # has reached the simulator through the router (a loaded machine): the mission
                # is flown again from the loiter at home, as an operator would, until the
                # observer hears the estimates. The bound is a safety bound, not a speed.
                end = time.monotonic() + SAFETY_S
                while not reached and time.monotonic() < end:
                    assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_ACCEPTED
                    reached = wait_until(lambda: len(heard) >= 5, timeout_s=AGAIN_AFTER_S)
            finally:
                gcs.close()
    finally:
        # The simulator first: the localizer then has no backlog of frames to finish.
        order = [procs[i] for i in (1, 2, 0) if i < len(procs)]
        stopped = [(str(proc.args), *stop(proc)) for proc in order]
        viewer.close()
    assert reached, ("no estimate reached the observer", stopped)
    frames = [json.loads(m.payload)["frame"] for m in heard[:5]]
    assert frames == sorted(frames)
    for args, code, _, err in stopped:
        # The example localizer's visual odometry runs slower than an unpaced simulator sends
        # frames: its zenoh session may time out closing over the backlog (not a routing
        # matter; at the compose file's --speed 1 it keeps up).
        if "bridges/example_localizer.py" not in args:
            assert code == 0, (args, err)
