"""The zenoh key space of one vehicle: every topic name lives here and nowhere else.

Contract version :data:`CONTRACT_VERSION` (also carried as ``"v"`` in every JSON message and
frame attachment). All keys live under ``air/<vehicle>/``. Adding a key or a JSON field is
compatible; renaming or removing one bumps the version.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import overload

from air_sitl.errors import OptionError

CONTRACT_VERSION = 1
DEFAULT_VEHICLE = "uav0"

# One key chunk: no '/', no zenoh wildcards or special characters.
_CHUNK = re.compile(r"[A-Za-z0-9_.-]+")


def check_chunk(what: str, value: str) -> str:
    """Validate a vehicle or estimator name used as one key chunk."""
    if not _CHUNK.fullmatch(value):
        msg = f"{what}: {value!r} is not a name of letters, digits, '_', '.' or '-'"
        raise OptionError(msg)
    return value


class _Key:
    """A key below ``air/<vehicle>``: read on a :class:`KeySpace`, the whole key."""

    __slots__ = ("suffix",)

    def __init__(self, suffix: str) -> None:
        self.suffix = suffix

    @overload
    def __get__(self, keys: None, owner: type[KeySpace]) -> _Key: ...
    @overload
    def __get__(self, keys: KeySpace, owner: type[KeySpace]) -> str: ...
    def __get__(self, keys: KeySpace | None, owner: type[KeySpace]) -> _Key | str:
        return self if keys is None else f"{keys.root}/{self.suffix}"


@dataclass(frozen=True, slots=True)
class KeySpace:
    """Keys of one vehicle, ``air/<vehicle>/...``."""

    vehicle: str = DEFAULT_VEHICLE

    # JPEG frames; attachment: JSON frame index and simulation time.
    image = _Key("camera/image")
    # Camera intrinsics, resolution, FOV, mounting (published once, and a queryable).
    info = _Key("camera/info")
    # Queryable of a camera bridge: truth pose in, JPEG frame out (remote camera).
    render = _Key("camera/render")
    # Gyro, accelerometer, AHRS quaternion.
    imu = _Key("imu")
    # Noisy GNSS fix; silent while GNSS is denied.
    gps = _Key("gps")
    # Ground-truth pose and velocity (only with ``--publish-truth``).
    truth = _Key("truth")
    # Autopilot mode, mission item, capture window, home.
    mission_status = _Key("mission/status")
    # Simulation time.
    clock = _Key("clock")
    # Every estimator of this vehicle (a wildcard for subscribers).
    estimates = _Key("estimate/*")

    def __post_init__(self) -> None:
        check_chunk("--vehicle", self.vehicle)

    @property
    def root(self) -> str:
        """``air/<vehicle>``."""
        return f"air/{self.vehicle}"

    def estimate(self, name: str) -> str:
        """Where the estimator ``name`` publishes its estimates."""
        return f"{self.root}/estimate/{check_chunk('estimator name', name)}"
