"""The autopilot's parameters: a PX4-named set with types, defaults and limits (params.csv).

The autopilot reads them at every guidance update, so a change (for example a PARAM_SET from
QGroundControl) takes effect in flight. The order of :data:`PARAMS` is the MAVLink
``param_index`` order and never changes at run time. As PX4, a set stores any finite value (a
ground station warns about values outside the range); whoever uses a value clamps it to the
range (:meth:`ParamStore.in_range`). Overrides given at start are checked against the range.
"""

from __future__ import annotations

import csv
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from importlib import resources

from air_sitl.errors import AirSitlError


class ParamError(AirSitlError):
    """An unknown parameter name, or a value outside the parameter's range."""


@dataclass(frozen=True, slots=True, kw_only=True)
class ParamSpec:
    """One parameter: PX4 name, default, inclusive range, integer or float, unit."""

    name: str
    default: float
    min_value: float
    max_value: float
    is_int: bool = False
    unit: str = ""
    description: str = ""


PARAMS_CSV = "params.csv"  # package data beside this module


def _spec_of(row: dict[str, str]) -> ParamSpec:
    """One row of :data:`PARAMS_CSV`; without min and max, any value of the type."""
    if row["type"] not in ("INT32", "REAL32"):
        msg = f"{PARAMS_CSV}: {row['name']}: type {row['type']!r}, expected INT32 or REAL32"
        raise ValueError(msg)
    is_int = row["type"] == "INT32"
    lo, hi = (-(2.0**31), 2.0**31 - 1) if is_int else (-1e9, 1e9)
    return ParamSpec(
        name=row["name"],
        default=float(row["default"]),
        min_value=float(row["min"]) if row["min"] else lo,
        max_value=float(row["max"]) if row["max"] else hi,
        is_int=is_int,
        unit=row["unit"],
        description=row["description"],
    )


def _load_params() -> tuple[ParamSpec, ...]:
    """The table of :data:`PARAMS_CSV` (``#`` lines are comments)."""
    text = resources.files("air_sitl.autopilot").joinpath(PARAMS_CSV).read_text(encoding="utf-8")
    lines = (line for line in text.splitlines() if not line.startswith("#"))
    return tuple(_spec_of(row) for row in csv.DictReader(lines))


# Every parameter in MAVLink param_index order: the autopilot's (with a range) and those PX4
# serves to ground stations at connect.
PARAMS: tuple[ParamSpec, ...] = _load_params()

_SPECS: dict[str, ParamSpec] = {spec.name: spec for spec in PARAMS}


class ParamStore:
    """Current values of :data:`PARAMS`, validated on every set.

    ``version`` increases on every change so readers can cache values derived from them.
    """

    def __init__(self, overrides: Mapping[str, float] | None = None) -> None:
        self._values: dict[str, float] = {spec.name: spec.default for spec in PARAMS}
        self.version = 0
        for name, value in (overrides or {}).items():
            self._check_range(name, value)
            self.set(name, value)

    @staticmethod
    def names() -> tuple[str, ...]:
        """All parameter names in MAVLink ``param_index`` order."""
        return tuple(spec.name for spec in PARAMS)

    @staticmethod
    def count() -> int:
        """Number of parameters (MAVLink ``param_count``)."""
        return len(PARAMS)

    @staticmethod
    def spec(name: str) -> ParamSpec:
        """The definition of ``name``; raises :class:`ParamError` for an unknown name."""
        try:
            return _SPECS[name]
        except KeyError:
            msg = f"parameter {name!r} does not exist, expected one of {', '.join(_SPECS)}"
            raise ParamError(msg) from None

    @staticmethod
    def index(name: str) -> int:
        """MAVLink ``param_index`` of ``name``."""
        ParamStore.spec(name)
        return next(i for i, spec in enumerate(PARAMS) if spec.name == name)

    def get(self, name: str) -> float:
        """Current value of ``name``."""
        try:
            return self._values[name]
        except KeyError:
            self.spec(name)  # raises with the list of names
            raise

    def set(self, name: str, value: float) -> float:
        """Store ``value`` as PX4 does, even outside the range; return the stored value
        (integers are rounded). Raises :class:`ParamError` for an unknown name or NaN/inf."""
        spec = self.spec(name)
        value = float(value)
        if not math.isfinite(value):
            msg = f"parameter {name}: value {value} is not a finite number"
            raise ParamError(msg)
        if spec.is_int:
            value = float(round(value))
        if self._values[name] != value:
            self._values[name] = value
            self.version += 1
        return value

    def _check_range(self, name: str, value: float) -> None:
        spec = self.spec(name)
        if not math.isfinite(value) or not spec.min_value <= value <= spec.max_value:
            msg = (
                f"parameter {name}: value {value} is outside "
                f"[{spec.min_value:g}, {spec.max_value:g}] {spec.unit}".rstrip()
            )
            raise ParamError(msg)

    def in_range(self, name: str) -> float:
        """The value of ``name`` clamped to its range: what the controller uses."""
        spec = self.spec(name)
        return min(spec.max_value, max(spec.min_value, self._values[name]))

    def items(self) -> Iterable[tuple[str, float]]:
        """(name, value) pairs in index order."""
        return ((spec.name, self._values[spec.name]) for spec in PARAMS)


@dataclass(frozen=True, slots=True)
class GuidanceParams:
    """The parameters guidance needs, converted to SI units once per change."""

    trim_m_s: float
    min_m_s: float
    max_m_s: float
    bank_limit_rad: float
    l1_period_s: float
    l1_damping: float
    acc_radius_m: float
    alt_acc_m: float
    loiter_radius_m: float
    climb_max_m_s: float
    sink_max_m_s: float
    climbout_diff_m: float
    takeoff_alt_m: float
    rtl_alt_m: float
    land_angle_rad: float
    land_airspeed_m_s: float

    @classmethod
    def from_store(cls, p: ParamStore) -> GuidanceParams:
        """Snapshot of the store."""
        lo = p.in_range("FW_AIRSPD_MIN")
        return cls(
            trim_m_s=p.in_range("FW_AIRSPD_TRIM"),
            min_m_s=lo,
            max_m_s=max(lo, p.in_range("FW_AIRSPD_MAX")),
            bank_limit_rad=math.radians(p.in_range("FW_R_LIM")),
            l1_period_s=p.in_range("NAV_L1_PERIOD"),
            l1_damping=p.in_range("NAV_L1_DAMPING"),
            acc_radius_m=p.in_range("NAV_ACC_RAD"),
            alt_acc_m=p.in_range("NAV_FW_ALT_RAD"),
            loiter_radius_m=p.in_range("NAV_LOITER_RAD"),
            climb_max_m_s=p.in_range("FW_T_CLMB_MAX"),
            sink_max_m_s=p.in_range("FW_T_SINK_MAX"),
            climbout_diff_m=p.in_range("FW_CLMBOUT_DIFF"),
            takeoff_alt_m=p.in_range("MIS_TAKEOFF_ALT"),
            rtl_alt_m=p.in_range("RTL_RETURN_ALT"),
            land_angle_rad=math.radians(p.in_range("FW_LND_ANG")),
            land_airspeed_m_s=p.in_range("FW_LND_AIRSPD"),
        )

    def clamp_speed(self, speed_m_s: float) -> float:
        """Airspeed within [FW_AIRSPD_MIN, FW_AIRSPD_MAX] (min(max, max(min, speed)) written
        out, choosing as the builtins do: guidance asks at 50 Hz)."""
        lo, hi = self.min_m_s, self.max_m_s
        v = speed_m_s if speed_m_s > lo else lo
        return v if v < hi else hi
