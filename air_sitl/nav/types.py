"""Value types of the navigation filter: its inputs beyond ImuSample/GpsFix, and its output.

Conventions (SPEC section 2): NED relative to home, body FRD, quaternions Hamilton
scalar-first ``(w, x, y, z)`` rotating body to NED, integer nanoseconds of simulation time.
No dependencies beyond :mod:`air_sitl.state`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass


@dataclass(frozen=True, slots=True, kw_only=True)
class BaroSample:
    """One barometric altitude reading (pressure altitude, AMSL, with noise and drift)."""

    sim_time_ns: int
    alt_amsl_m: float


@dataclass(frozen=True, slots=True, kw_only=True)
class AirspeedSample:
    """One true-airspeed reading of the pitot-static sensor."""

    sim_time_ns: int
    airspeed_m_s: float


@dataclass(frozen=True, slots=True, kw_only=True)
class HeadingSample:
    """One magnetic heading reading (0 = magnetic north, clockwise positive)."""

    sim_time_ns: int
    heading_rad: float


class AidFrame(enum.Enum):
    """Frames an external position aid may use (anything else is rejected as unknown)."""

    ENU = "enu"  # [east, north, up] metres from home (zenoh estimate/<name> enu_m)
    NED = "ned"  # [north, east, down] metres from home (MAVLink MAV_FRAME_LOCAL_NED)
    WGS84 = "wgs84"  # [lat_deg, lon_deg, alt_amsl_m] (GPS_INPUT, estimate lat/lon/alt)


@dataclass(frozen=True, slots=True, kw_only=True)
class AidMeasurement:
    """A position from an external aid (a map-based localizer, VISION_POSITION_ESTIMATE ...).

    ``position`` is None (or all NaN) for "no estimate for this frame": counted as empty.
    ``cov_m2`` is the 3x3 row-major covariance in the measurement's frame axes (for WGS84:
    east, north, up metres); without it ``sigma_m`` (or the filter's default) is used.
    ``frame`` is a string on purpose: input from a bus is checked by the filter, which counts
    an unknown frame as a rejection instead of raising.
    """

    name: str
    sim_time_ns: int
    position: tuple[float, float, float] | None
    frame: str = AidFrame.ENU.value
    cov_m2: tuple[float, ...] | None = None
    sigma_m: float | None = None


class AidResult(enum.Enum):
    """What :meth:`NavFilter.fuse_aid` did with one measurement on arrival."""

    ACCEPTED = "accepted"  # buffered; gated then fused when the fusion horizon reaches it
    EMPTY = "empty"  # no position: neither fused nor rejected
    REJECTED_INVALID = "invalid"  # NaN/inf, wrong shape, bad covariance or sigma
    REJECTED_FRAME = "frame"  # unknown frame
    REJECTED_FUTURE = "future"  # stamped after now
    REJECTED_STALE = "stale"  # stamped behind the fusion horizon
    REJECTED_RATE = "rate"  # closer in time than the minimum interval to the previous one
    REJECTED_ORDER = "order"  # older than the previous accepted one of the same aid
