"""MAVLink endpoint: 500-item mission upload with MAVSDK, and telemetry jitter at --speed 1.

Usage: python benchmarks/bench_mavlink.py [--items 500] [--jitter-seconds 10]

Starts ``air-sitl serve`` (real process, loopback). Upload: wall time of MAVSDK's
``upload_mission`` of N items (target under 1 s), beside pymavlink doing the same by hand and
the floor of N bare UDP request/response round trips between two Python sockets. Jitter: the
spacing of ATTITUDE (20 Hz) and HEARTBEAT (1 Hz) as a pymavlink client receives them at
--speed 1, beside the floor of a Python loop sleeping 50 ms.
"""

from __future__ import annotations

import argparse
import asyncio
import itertools
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

HOME = (38.5125, -121.4935, 7.0)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@contextmanager
def serve(*links: str, speed: float = 1.0) -> Iterator[list[int]]:
    """``air-sitl serve`` with the given links; yields the local ports."""
    args = [a for link in links for a in ("--mavlink", link)]
    home = ",".join(str(v) for v in HOME)
    cmd = [sys.executable, "-m", "air_sitl", "serve", *args, "--home", home, "--speed", str(speed)]
    cmd.append("--no-video")  # MAVLink alone: the stream would share the cores
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1")
    )
    try:
        assert proc.stdout is not None
        banner = proc.stdout.readline()
        yield [int(p) for p in re.findall(r"\(local [^:]+:(\d+)\)", banner)]
    finally:
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=15)


def waypoints(n: int) -> list[tuple[int, int, int, float, float, float]]:
    """(command, frame, seq, lat, lon, alt): a take-off then a lawnmower of waypoints."""
    items = [(22, 3, 0, HOME[0] + 0.005, HOME[1], 100.0)]
    for seq in range(1, n):
        row, col = divmod(seq, 25)
        lon = HOME[1] + 0.0005 * (col if row % 2 == 0 else 24 - col)
        items.append((16, 3, seq, HOME[0] + 0.006 + 0.0005 * row, lon, 100.0))
    return items


async def mavsdk_upload(port: int, n: int, repeats: int) -> list[float]:
    from mavsdk.asyncio import ComponentType, Configuration, Mavsdk
    from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
    from mavsdk.plugins.mission_raw import MissionItem

    items = [
        MissionItem(
            seq=seq, frame=frame, command=cmd, current=int(seq == 0), autocontinue=1,
            param1=15.0 if cmd == 22 else 0.0, param4=float("nan"),
            x=round(lat * 1e7), y=round(lon * 1e7), z=alt, mission_type=0,
        )
        for cmd, frame, seq, lat, lon, alt in waypoints(n)
    ]  # fmt: skip
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await sdk.first_autopilot(timeout_s=15)
        assert system is not None
        mission = MissionRawAsync(system)
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            await mission.upload_mission(items)
            times.append(time.perf_counter() - t0)
        downloaded = await mission.download_mission()
        assert len(downloaded) == n
        return times


def pymavlink_upload(port: int, n: int) -> float:
    from pymavlink import mavutil

    conn: Any = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=255, source_component=190
    )
    conn.mav.heartbeat_send(6, 8, 0, 0, 0)
    conn.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    items = waypoints(n)
    t0 = time.perf_counter()
    conn.mav.mission_count_send(1, 1, n, 0)
    while True:
        msg = conn.recv_match(type=["MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=5)
        assert msg is not None
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == 0
            break
        cmd, frame, seq, lat, lon, alt = items[msg.seq]
        conn.mav.mission_item_int_send(
            1, 1, seq, frame, cmd, 0, 1, 15.0, 0, 0, float("nan"),
            round(lat * 1e7), round(lon * 1e7), alt, 0,
        )  # fmt: skip
    elapsed = time.perf_counter() - t0
    conn.close()
    return elapsed


def udp_round_trip_floor(n: int) -> float:
    """N request/response exchanges between two Python UDP sockets: the protocol's floor."""
    a = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    b = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    a.bind(("127.0.0.1", 0))
    b.bind(("127.0.0.1", 0))
    payload = bytes(60)
    t0 = time.perf_counter()
    for _ in range(n):
        a.sendto(payload, b.getsockname())
        data, addr = b.recvfrom(1024)
        b.sendto(data, addr)
        a.recvfrom(1024)
    elapsed = time.perf_counter() - t0
    a.close()
    b.close()
    return elapsed


def intervals(port: int, seconds: float) -> dict[str, list[float]]:
    from pymavlink import mavutil

    conn: Any = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{port}", source_system=255, source_component=190
    )
    conn.mav.heartbeat_send(6, 8, 0, 0, 0)
    conn.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    arrivals: dict[str, list[float]] = {"ATTITUDE": [], "HEARTBEAT": []}
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        msg = conn.recv_match(type=list(arrivals), blocking=True, timeout=0.1)
        if msg is not None:
            arrivals[msg.get_type()].append(time.perf_counter())
    conn.close()
    return {k: [b - a for a, b in itertools.pairwise(v)] for k, v in arrivals.items()}


def sleep_floor(period_s: float, count: int) -> list[float]:
    out = []
    last = time.perf_counter()
    for _ in range(count):
        time.sleep(period_s)
        now = time.perf_counter()
        out.append(now - last)
        last = now
    return out


def describe(name: str, gaps: list[float], period_s: float) -> str:
    dev = sorted(abs(g - period_s) * 1000 for g in gaps)
    p99 = dev[int(0.99 * (len(dev) - 1))] if dev else float("nan")
    mean = statistics.fmean(gaps) * 1000 if gaps else float("nan")
    sd = statistics.pstdev(gaps) * 1000 if len(gaps) > 1 else float("nan")
    return (
        f"  {name:<28} n={len(gaps):4d} mean {mean:7.2f} ms  sd {sd:6.2f} ms  "
        f"p99 |dev| {p99:6.2f} ms  max |dev| {max(dev, default=float('nan')):6.2f} ms"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--items", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--jitter-seconds", type=float, default=10.0)
    args = parser.parse_args()
    n = args.items

    port = free_udp_port()
    with serve(f"udpout:127.0.0.1:{port}", "udpin:127.0.0.1:0") as ports:
        sdk_times = asyncio.run(mavsdk_upload(port, n, args.repeats))
        pym = pymavlink_upload(ports[1], n)
    floor = udp_round_trip_floor(n)
    best = min(sdk_times)
    print(f"{n}-item mission upload (wall):")
    print(f"  MAVSDK upload_mission    best {best:.3f} s  all {[round(t, 3) for t in sdk_times]}")
    print(f"  target under 1 s: {'met' if best < 1.0 else 'NOT met'}")
    print(f"  pymavlink by hand        {pym:.3f} s")
    print(f"  floor: {n} bare UDP round trips {floor:.3f} s  (MAVSDK / floor = {best / floor:.1f})")

    with serve("udpin:127.0.0.1:0", speed=1.0) as ports:
        gaps = intervals(ports[0], args.jitter_seconds)
    floor_gaps = sleep_floor(0.05, int(args.jitter_seconds * 20))
    print(f"telemetry spacing at --speed 1 over {args.jitter_seconds:g} s (client receive times):")
    print(describe("ATTITUDE (20 Hz)", gaps["ATTITUDE"], 0.05))
    print(describe("HEARTBEAT (1 Hz)", gaps["HEARTBEAT"], 1.0))
    print(describe("floor: time.sleep(0.05)", floor_gaps, 0.05))


if __name__ == "__main__":
    main()
