"""The localizer contract: one object per method, ``reset(context)`` then ``step(observation)``.

Gymnasium-wrapper style. An offline driver (an archive, :mod:`air_sitl.localize.archive`) and
an online driver (the zenoh bus, :mod:`air_sitl.localize.online`) build the same
:class:`Observation` per camera frame and feed it to the same method object, so a method never
knows where its inputs come from.

Conventions (SPEC section 2): NED relative to home, body FRD, quaternions Hamilton
scalar-first ``(w, x, y, z)`` rotating body to NED, integer nanoseconds of simulation time.
Estimates are ENU metres relative to home (what ``estimates/<name>.csv`` and the bus carry).
This module imports nothing heavy (numpy only for the image type).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from air_sitl.camera.model import CameraModel
from air_sitl.state import GeoPoint, ImuSample, Quat, Vec3

Image = npt.NDArray[np.uint8]


# One raw IMU sample (noise, bias and AHRS drift included): the simulator's own type.
ImuReading = ImuSample


@dataclass(frozen=True, slots=True, kw_only=True)
class GnssFix:
    """One GNSS fix as the receiver reports it (noisy)."""

    sim_time_ns: int
    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    vel_ned_m_s: Vec3


@dataclass(frozen=True, slots=True, kw_only=True)
class Observation:
    """Everything a method may use at one camera frame, and nothing more.

    ``gnss`` is given only at the first capture frame, and outside the GNSS denial windows an
    archive records (``manifest.json`` ``gps_denied``); see the drivers for what each source
    can and cannot provide (``airspeed_m_s`` / ``baro_alt_rel_m`` None when unavailable).
    """

    frame: int  # 0-based index in the capture window
    sim_time_ns: int  # exposure time
    image_bgr: Image | None  # None when the method says it needs no image
    imu: tuple[ImuReading, ...]  # the IMU samples since the previous observation, in order
    q_ahrs_body_to_ned_wxyz: Quat  # on-board AHRS attitude at the exposure
    airspeed_m_s: float | None  # true airspeed measurement
    baro_alt_rel_m: float | None  # barometric height above home
    gnss: GnssFix | None  # a fix given at this frame, or None
    jpeg: bytes | None = None  # the encoded frame (both drivers have it; see needs_image)


@dataclass(frozen=True, slots=True, kw_only=True)
class LocalizerContext:
    """What a method knows before the first frame."""

    home: GeoPoint
    camera: CameraModel
    frame_rate_hz: float = 50.0
    map_date: int | None = None  # the date the flight's frames were rendered at, when known
    map_name: str | None = None  # the flight's map source (manifest ``map``), when known
    reference_map: str | None = None  # the map a map-matching method matches against
    reference_date: int | None = None  # and its date (None: the flight's own)
    seed: int = 0
    manifest: dict[str, Any] | None = None  # the archive's manifest.json (None on the bus)
    extras: dict[str, Any] = field(default_factory=dict)  # driver/method specific additions


@dataclass(frozen=True, slots=True, kw_only=True)
class Estimate:
    """A method's answer for one frame; ``enu_m`` None means "no estimate for this frame"."""

    frame: int
    sim_time_ns: int
    enu_m: Vec3 | None  # east, north, up in metres relative to home
    cov_enu_m2: tuple[float, ...] | None = None  # 3x3 row-major
    quality: float | None = None  # method-specific confidence in [0, 1], when it has one
    q_body_to_ned_wxyz: Quat | None = None
    # A map fix accepted at this frame (True), tried or propagated without one (False); None
    # for a method without map fixes. ``estimates/<name>.csv``'s ``fix`` column.
    fix: bool | None = None


@runtime_checkable
class Localizer(Protocol):
    """A localization method: one object, reset once per flight, stepped once per frame."""

    name: str
    # True: drivers decode every frame to BGR (``image_bgr``). False: they do not
    # (``image_bgr`` None); ``jpeg`` carries the encoded frame either way, so a method that
    # wants it in grey at reduced size decodes it itself, cheaper (vo, mapmatch do).
    needs_image: bool
    # Optional (absent: True): False declares that the method reads neither the frames (no
    # ``image_bgr``, no ``jpeg``) nor the map or its date, only the flight's other inputs
    # (:func:`~air_sitl.localize.methods.reads_imagery`): its estimates over the archives
    # of one flight rendered at several map dates are the same, so a sweep or a bench
    # computes them once per flight and reuses them for the other dates.

    def reset(self, context: LocalizerContext) -> None:
        """Start a new flight (drop all state)."""
        ...

    def step(self, obs: Observation) -> Estimate | None:
        """The estimate at this frame; None (or ``enu_m`` None) when it cannot tell."""
        ...
