"""Shared pieces of the bus tests: free loopback endpoints, synthetic samples, processes."""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

from ports import free_port
from vehicle_states import airborne_state

from air_sitl.bus.session import Bus, BusConfig, open_bus
from air_sitl.frames import ned2geodetic
from air_sitl.state import (
    CameraTick,
    GeoPoint,
    GpsFix,
    SimSample,
    mission_sample,
)

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


def free_endpoint() -> str:
    """A loopback TCP endpoint on a port nobody uses right now (this worker's range)."""
    return f"tcp/127.0.0.1:{free_port()}"


def pair(endpoint: str) -> tuple[Bus, Bus]:
    """Two peer sessions: the first listens (a simulator), the second connects to it."""
    a = open_bus(BusConfig(listen=(endpoint,), connect=(), serves=True))
    b = open_bus(BusConfig(listen=(), connect=(endpoint,)))
    return a, b


SAFETY_S = 120.0  # wall seconds: only a stuck peer gets there (the machine may be loaded)
# fly's --wait-for gives up after 10 wall seconds without a subscriber or an estimate; a
# localizer starting beside a loaded suite (imports, its reference map) can take longer.
WAIT_SAFETY = ("--wait-timeout", str(SAFETY_S))
# Frames whose pixels nobody looks at (a truth aid, dead reckoning, a counting subscriber):
# 160 x 120 without noise. A 640 x 480 frame's render and JPEG were most of such a flight's CPU.


def wait_until(cond: Callable[[], bool], timeout_s: float = SAFETY_S) -> bool:
    """Wait for the event ``cond`` (polled); ``timeout_s`` is a safety bound, not a speed."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.01)
    return cond()


def make_sample(
    t_ns: int,
    *,
    east_m: float = 0.0,
    alt_agl_m: float = 200.0,
    yaw_rad: float = math.pi / 2,
    capturing: bool = True,
    gps: bool = False,
    frame: int | None = None,
) -> SimSample:
    """A level aircraft flying east at ``east_m`` from home, ``alt_agl_m`` high (``frame``: a
    camera exposure of that index, inside the capture window when ``capturing``)."""
    lat, lon, alt = ned2geodetic(
        0.0, east_m, -alt_agl_m, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m
    )
    state = airborne_state(
        t_ns,
        lat_deg=lat,
        lon_deg=lon,
        alt_amsl_m=alt,
        alt_agl_m=alt_agl_m,
        pos_ned_m=(0.0, east_m, -alt_agl_m),
        rpy_rad=(0.0, 0.0, yaw_rad),
        vel_ned_m_s=(0.0, 15.0, 0.0),
        specific_force_frd_m_s2=(0.0, 0.0, -9.80665),
    )
    fix = None
    if gps:
        fix = GpsFix(
            sim_time_ns=t_ns,
            lat_deg=lat,
            lon_deg=lon,
            alt_amsl_m=alt,
            vel_ned_m_s=(0.0, 15.0, 0.0),
            fix_type=3,
            satellites=14,
            eph_m=1.5,
            epv_m=3.0,
        )
    tick = None
    if frame is not None:
        tick = CameraTick(index=frame, capture_index=frame if capturing else None)
    sample = mission_sample(state, capturing=capturing, current_seq=2)
    return dataclasses.replace(sample, gps=fix, camera=tick)


def cli(*args: str) -> list[str]:
    """Command line of ``air-sitl ARGS`` with this interpreter."""
    return [sys.executable, "-m", "air_sitl", *args]


def fly_with_bus_localizer(localize: list[str], fly: list[str]) -> str:
    """``air-sitl localize --bus LOCALIZE`` and ``air-sitl fly FLY`` as two processes on a free
    endpoint (fly listens, the localizer connects); both must exit 0 (the localizer leaves by
    itself when the flight ends). The localizer's stdout."""
    endpoint = free_endpoint()
    loc = subprocess.Popen(
        cli("localize", "--bus", *localize, "--zenoh-connect", endpoint),
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        flown = subprocess.run(
            cli("fly", *fly, "--zenoh-listen", endpoint, *WAIT_SAFETY),
            capture_output=True, text=True, timeout=600, check=False,
        )  # fmt: skip
        assert flown.returncode == 0, flown.stderr
        loc_out, loc_err = loc.communicate(timeout=60)
    finally:
        if loc.poll() is None:
            loc.kill()
            loc.communicate()
    assert loc.returncode == 0, loc_err
    return loc_out


def start(cmd: list[str], **kwargs: object) -> subprocess.Popen[str]:
    """Start a process with captured text output."""
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    return subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, **kwargs
    )


def wait_for_line(proc: subprocess.Popen[str], text: str, timeout_s: float = SAFETY_S) -> str:
    """Read stdout until a line containing ``text`` (fails on exit or timeout)."""
    assert proc.stdout is not None
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        line = proc.stdout.readline()
        if text in line:
            return line
        if not line and proc.poll() is not None:
            break
    raise AssertionError(f"no line with {text!r} from {proc.args}")


def stop(proc: subprocess.Popen[str], sig: int = signal.SIGINT) -> tuple[int, str, str]:
    """Signal the process, wait, return (exit code, rest of stdout, stderr)."""
    if proc.poll() is None:
        proc.send_signal(sig)
    try:
        out, err = proc.communicate(timeout=20)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
    return proc.returncode, out, err
