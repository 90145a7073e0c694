"""A localization program of the user's flown in lockstep with a flight (bench and sweep).

The program joins the bus of ``air-sitl fly --zenoh --wait-for NAME`` on a free loopback port:
``{endpoint}`` in its command is replaced by the endpoint, else ``--zenoh-connect ENDPOINT`` is
appended (what air-sitl's own bus programs take); ``AIR_SITL_ZENOH_ENDPOINT`` is set too. Its
answers land in the flight's ``estimates/NAME.csv``; :func:`adopt_estimates` moves them into
the archive of the same flight.

The port is found free by binding port 0 and releasing it; another program may take it before
the flight listens on it. The flight then cannot open its bus and says so at once: the
program is stopped and both start again on another port (:data:`PORT_ATTEMPTS` in all).
"""

from __future__ import annotations

import os
import shutil
import signal
import socket
import subprocess
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from air_sitl.bus.session import OPEN_FAILED
from air_sitl.dataset.air_schema import ESTIMATES_DIR, TRAJECTORY_CSV
from air_sitl.dataset.manifest import refresh_manifest, sha256_bytes
from air_sitl.files import write_bytes_atomic

SHUTDOWN_GRACE_S = 10.0  # a program gets this long to exit after SIGINT (then SIGKILL)
PORT_ATTEMPTS = 5  # ports tried when the one picked was taken before the flight listened


@dataclass(frozen=True, slots=True, kw_only=True)
class ExternalLocalizer:
    """A localizer program run on the bus in lockstep: ``NAME=COMMAND``."""

    name: str
    argv: tuple[str, ...]


def free_port() -> int:
    """A TCP port on loopback that nothing listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def localizer_argv(localizer: ExternalLocalizer, endpoint: str) -> list[str]:
    """The user's command with the bus endpoint: ``{endpoint}`` replaced, else appended as
    ``--zenoh-connect ENDPOINT``."""
    if any("{endpoint}" in arg for arg in localizer.argv):
        return [arg.replace("{endpoint}", endpoint) for arg in localizer.argv]
    return [*localizer.argv, "--zenoh-connect", endpoint]


def stop(proc: subprocess.Popen[bytes]) -> None:
    """SIGINT, then SIGKILL after :data:`SHUTDOWN_GRACE_S`; nothing when it has exited."""
    if proc.poll() is not None:
        return
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(SHUTDOWN_GRACE_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def fly_in_lockstep(
    plan: Path, fly_args: Sequence[str], out: Path, localizer: ExternalLocalizer, log_path: Path
) -> str | None:
    """``air-sitl fly PLAN FLY_ARGS --out OUT`` on a bus of its own, every frame waiting for the
    localizer's answer; the program's output goes to ``log_path``. None, or why it failed in
    one line (the flight's last error line). A port taken before the flight listened on it is
    replaced by another (up to :data:`PORT_ATTEMPTS` ports)."""
    with log_path.open("wb") as log:
        for _ in range(PORT_ATTEMPTS - 1):
            endpoint = f"tcp/127.0.0.1:{free_port()}"
            why, taken = _fly_once(plan, fly_args, out, localizer, endpoint, log)
            if not taken:
                return why
            shutil.rmtree(out, ignore_errors=True)  # what the failed start left, if anything
            log.write(f"air-sitl: {endpoint} was taken; again on another port\n".encode())
            log.flush()
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        return _fly_once(plan, fly_args, out, localizer, endpoint, log)[0]


def _fly_once(
    plan: Path,
    fly_args: Sequence[str],
    out: Path,
    localizer: ExternalLocalizer,
    endpoint: str,
    log: BinaryIO,
) -> tuple[str | None, bool]:
    """One lockstep flight with the bus on ``endpoint``: (None or why it failed, whether the
    flight could not listen there)."""
    cmd = [
        sys.executable, "-m", "air_sitl", "fly", str(plan), *fly_args, "--out", str(out),
        "--quiet", "--zenoh", f"--zenoh-listen={endpoint}", f"--wait-for={localizer.name}",
    ]  # fmt: skip
    env = {**os.environ, "AIR_SITL_ZENOH_ENDPOINT": endpoint}
    fly = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        user = subprocess.Popen(
            localizer_argv(localizer, endpoint), stdout=log, stderr=log, env=env
        )
    except OSError as err:
        stop(fly)
        return f"cannot start {localizer.argv[0]}: {err.strerror or err}", False
    try:
        _, fly_err = fly.communicate()
    finally:
        stop(fly)
        stop(user)
    if fly.returncode == 0:
        return None, False
    lines = fly_err.decode("utf-8", "replace").strip().splitlines()
    last = lines[-1] if lines else f"fly exited with {fly.returncode}"
    return last, OPEN_FAILED in last and endpoint in last


def same_flight(flight: Path, archive: Path) -> bool:
    """Whether the lockstep flight flew as the archive's did (trajectory.csv byte for byte)."""
    return (flight / TRAJECTORY_CSV).read_bytes() == (archive / TRAJECTORY_CSV).read_bytes()


def adopt_estimates(flight: Path, archive: Path, name: str) -> None:
    """Copy the flight's ``estimates/NAME.csv`` into ``archive`` (atomically; in its manifest)."""
    relative = f"{ESTIMATES_DIR}/{name}.csv"
    data = (flight / relative).read_bytes()
    (archive / ESTIMATES_DIR).mkdir(exist_ok=True)
    write_bytes_atomic(archive / relative, data)
    refresh_manifest(archive, {relative: sha256_bytes(data)})
