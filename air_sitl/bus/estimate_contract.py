"""The contract an estimate on ``estimate/<name>`` must keep, checked field by field (pure).

An estimator is a program we do not control: anything may arrive. :func:`check_estimate`
turns a payload into a :class:`~air_sitl.bus.codec.Estimate` or raises
:class:`EstimateRejectedError` with a *reason* (one of :data:`REASONS`) the flight counts, and one
line naming the key and the value. Only what the payload says is checked here; whether its
frame or time lies inside the flight, and whether the frame was answered already, is the
estimate log's to judge (:mod:`air_sitl.bus.estimates`), with the same reasons.

Plausible magnitudes: positions within :data:`MAX_ENU_M` of home on each axis, altitudes in
:data:`ALT_AMSL_RANGE_M`, a quaternion of norm 1 within :data:`QUAT_NORM_TOLERANCE`,
covariances finite with a non-negative diagonal. ``null`` (or NaN) coordinates remain the
contract's "no estimate for this frame". ``fix``, optional, is a JSON boolean: a map fix was
accepted at this frame (``true``) or not (``false``); absent or ``null``: the estimator does not
say.
"""

from __future__ import annotations

import json
import math
from typing import Any

from air_sitl.errors import BusError
from air_sitl.state import GeoPoint, Quat, Vec3

MAX_ENU_M = 1.0e6  # 1000 km from home on any axis: no fixed-wing flight of ours goes there
ALT_AMSL_RANGE_M = (-1000.0, 100_000.0)
QUAT_NORM_TOLERANCE = 0.1
MAX_COV_M2 = 1.0e12

# Why an estimate was not taken (the keys of summary.json's ``estimates_rejected``).
MALFORMED = "malformed"  # not a JSON object, a field of the wrong type, a number out of range
NO_FRAME_OR_TIME = "no_frame_or_time"
NON_FINITE = "non_finite"
IMPLAUSIBLE = "implausible"
OUTSIDE_FLIGHT = "outside_flight"  # a frame never exposed, a time before or after the flight
DUPLICATE = "duplicate_frame"  # a frame (or time) already answered: the first estimate counts
TOO_MANY_NAMES = "too_many_names"  # beyond --max-estimate-names
REASONS = (
    MALFORMED,
    NO_FRAME_OR_TIME,
    NON_FINITE,
    IMPLAUSIBLE,
    OUTSIDE_FLIGHT,
    DUPLICATE,
    TOO_MANY_NAMES,
)


class EstimateRejectedError(BusError):
    """An estimate that breaks the contract; ``reason`` is one of :data:`REASONS`."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


def check_estimate(payload: bytes, what: str) -> dict[str, Any]:
    """The checked fields of one estimate: ``frame``, ``sim_time_ns`` (int or None), ``enu_m``
    (Vec3 or None), ``geo``, ``q``, ``cov`` and ``fix`` (or None); EstimateRejectedError
    otherwise."""
    m = _json_object(payload, what)
    try:
        fields = _fields(m, what)
    except (KeyError, TypeError, ValueError, IndexError, OverflowError) as err:
        msg = f"{what}: bad estimate ({type(err).__name__}: {_short(err)})"
        raise EstimateRejectedError(MALFORMED, msg) from None
    _check_magnitudes(fields, what)
    return fields


def _json_object(payload: bytes, what: str) -> dict[str, Any]:
    try:
        value = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError, ValueError) as err:
        msg = f"{what}: not a JSON object ({type(err).__name__}: {_short(err)})"
        raise EstimateRejectedError(MALFORMED, msg) from None
    if not isinstance(value, dict):
        msg = f"{what}: expected a JSON object, got {type(value).__name__}"
        raise EstimateRejectedError(MALFORMED, msg)
    return value


def _short(err: BaseException) -> str:
    text = str(err).splitlines()[0] if str(err) else ""
    return text[:120]


def _index(value: Any, name: str, what: str) -> int | None:
    """A non-negative integer (an integral float is taken: JSON writers differ) or None."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        msg = f"{what}: {name!r} must be an integer, got {type(value).__name__}"
        raise EstimateRejectedError(MALFORMED, msg)
    if isinstance(value, float) and not (math.isfinite(value) and value.is_integer()):
        msg = f"{what}: {name!r} must be an integer, got {value!r}"
        raise EstimateRejectedError(NON_FINITE if not math.isfinite(value) else MALFORMED, msg)
    number = int(value)
    if number < 0:
        msg = f"{what}: {name!r} {number} is negative (before the flight)"
        raise EstimateRejectedError(OUTSIDE_FLIGHT, msg)
    return number


def _numbers(value: Any, count: int, name: str, what: str, *, nulls: bool) -> tuple[float, ...]:
    if not isinstance(value, list) or len(value) != count:
        msg = f"{what}: {name!r} needs {count} numbers"
        raise EstimateRejectedError(MALFORMED, msg)
    out = []
    for v in value:
        if v is None and nulls:
            out.append(math.nan)
        elif isinstance(v, bool) or not isinstance(v, int | float):
            msg = f"{what}: {name!r} holds {type(v).__name__}, expected numbers"
            raise EstimateRejectedError(MALFORMED, msg)
        else:
            out.append(float(v))
    return tuple(out)


def _fields(m: dict[str, Any], what: str) -> dict[str, Any]:
    frame = _index(m.get("frame"), "frame", what)
    t = _index(m.get("sim_time_ns"), "sim_time_ns", what)
    if frame is None and t is None:
        msg = f"{what}: needs 'frame' or 'sim_time_ns'"
        raise EstimateRejectedError(NO_FRAME_OR_TIME, msg)
    enu: Vec3 | None = None
    if m.get("enu_m") is not None:
        e, n, u = _numbers(m["enu_m"], 3, "enu_m", what, nulls=True)
        enu = (e, n, u)
    geo = None
    if m.get("lat_deg") is not None:
        lat, lon, alt = (
            _numbers([m.get(k) for k in ("lat_deg", "lon_deg", "alt_amsl_m")], 3, "lat/lon/alt",
                     what, nulls=False)
        )  # fmt: skip
        geo = GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
    q: Quat | None = None
    if m.get("q_body_to_ned_wxyz") is not None:
        w, x, y, z = _numbers(m["q_body_to_ned_wxyz"], 4, "q_body_to_ned_wxyz", what, nulls=False)
        q = (w, x, y, z)
    cov = None
    if m.get("cov_enu_m2") is not None:
        cov = _numbers(m["cov_enu_m2"], 9, "cov_enu_m2 (3x3 row-major)", what, nulls=False)
    fix = m.get("fix")
    if fix is not None and not isinstance(fix, bool):
        msg = f"{what}: 'fix' must be true, false or null, got {json.dumps(fix)[:40]}"
        raise EstimateRejectedError(MALFORMED, msg)
    return {
        "frame": frame, "sim_time_ns": t, "enu_m": enu, "geo": geo, "q": q, "cov": cov, "fix": fix
    }  # fmt: skip


def _check_magnitudes(f: dict[str, Any], what: str) -> None:
    enu, geo, q, cov = f["enu_m"], f["geo"], f["q"], f["cov"]
    values = [
        *(c for c in (enu or ()) if not math.isnan(c)),
        *((geo.lat_deg, geo.lon_deg, geo.alt_amsl_m) if geo else ()),
        *(q or ()),
        *(cov or ()),
    ]
    if not all(math.isfinite(v) for v in values):
        msg = f"{what}: non-finite number in the estimate"
        raise EstimateRejectedError(NON_FINITE, msg)
    problem = ""
    if enu is not None and any(abs(c) > MAX_ENU_M for c in enu if not math.isnan(c)):
        problem = f"enu_m {list(enu)} farther than {MAX_ENU_M:g} m from home"
    elif geo is not None and not (-90.0 <= geo.lat_deg <= 90.0 and -180.0 <= geo.lon_deg <= 180.0):
        problem = f"lat/lon {geo.lat_deg}, {geo.lon_deg} out of range"
    elif geo is not None and not ALT_AMSL_RANGE_M[0] <= geo.alt_amsl_m <= ALT_AMSL_RANGE_M[1]:
        low, high = ALT_AMSL_RANGE_M
        problem = f"alt_amsl_m {geo.alt_amsl_m} outside [{low:g}, {high:g}] m"
    elif q is not None and abs(math.sqrt(sum(c * c for c in q)) - 1.0) > QUAT_NORM_TOLERANCE:
        problem = f"q_body_to_ned_wxyz {list(q)} is not a unit quaternion"
    elif cov is not None and (
        any(cov[i] < 0.0 for i in (0, 4, 8)) or any(abs(c) > MAX_COV_M2 for c in cov)
    ):
        problem = "cov_enu_m2 has a negative variance or a value beyond 1e12 m^2"
    if problem:
        msg = f"{what}: {problem}"
        raise EstimateRejectedError(IMPLAUSIBLE, msg)
