"""The zenoh key space of one vehicle: every topic name lives here and nowhere else.

Contract version :data:`CONTRACT_VERSION` (also carried as ``"v"`` in every JSON message and
frame attachment). All keys live under ``air/<vehicle>/``. Adding a key or a JSON field is
compatible; renaming or removing one bumps the version.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

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


@dataclass(frozen=True, slots=True)
class KeySpace:
    """Keys of one vehicle, ``air/<vehicle>/...``."""

    vehicle: str = DEFAULT_VEHICLE

    def __post_init__(self) -> None:
        check_chunk("--vehicle", self.vehicle)

    @property
    def root(self) -> str:
        """``air/<vehicle>``."""
        return f"air/{self.vehicle}"

    @property
    def image(self) -> str:
        """JPEG frames; attachment: JSON frame index and simulation time."""
        return f"{self.root}/camera/image"

    @property
    def info(self) -> str:
        """Camera intrinsics, resolution, FOV, mounting (published once, and a queryable)."""
        return f"{self.root}/camera/info"

    @property
    def render(self) -> str:
        """Queryable of a camera bridge: truth pose in, JPEG frame out (remote camera)."""
        return f"{self.root}/camera/render"

    @property
    def imu(self) -> str:
        """Gyro, accelerometer, AHRS quaternion."""
        return f"{self.root}/imu"

    @property
    def gps(self) -> str:
        """Noisy GNSS fix; silent while GNSS is denied."""
        return f"{self.root}/gps"

    @property
    def truth(self) -> str:
        """Ground-truth pose and velocity (only with ``--publish-truth``)."""
        return f"{self.root}/truth"

    @property
    def mission_status(self) -> str:
        """Autopilot mode, mission item, capture window, home."""
        return f"{self.root}/mission/status"

    @property
    def clock(self) -> str:
        """Simulation time."""
        return f"{self.root}/clock"

    def estimate(self, name: str) -> str:
        """Where the estimator ``name`` publishes its estimates."""
        return f"{self.root}/estimate/{check_chunk('estimator name', name)}"

    @property
    def estimates(self) -> str:
        """Every estimator of this vehicle (a wildcard for subscribers)."""
        return f"{self.root}/estimate/*"
