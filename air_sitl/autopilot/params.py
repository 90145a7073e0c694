"""The autopilot's parameters: a PX4-named set with types, defaults and limits.

The autopilot reads them at every guidance update, so a change (for example a PARAM_SET from
QGroundControl) takes effect in flight. The order of :data:`PARAMS` is the MAVLink
``param_index`` order and never changes at run time. As PX4, a set stores any finite value (a
ground station warns about values outside the range); whoever uses a value clamps it to the
range (:meth:`ParamStore.in_range`). Overrides given at start are checked against the range.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from air_sitl.autopilot.px4_params import PX4_CONNECT_PARAMS
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


PARAMS: tuple[ParamSpec, ...] = (
    ParamSpec(
        name="FW_AIRSPD_TRIM",
        default=15.0,
        min_value=5.0,
        max_value=100.0,
        unit="m/s",
        description="cruise airspeed outside missions, and in missions without a plan speed",
    ),
    ParamSpec(
        name="FW_AIRSPD_MIN",
        default=12.0,
        min_value=5.0,
        max_value=100.0,
        unit="m/s",
        description="lowest airspeed the autopilot commands",
    ),
    ParamSpec(
        name="FW_AIRSPD_MAX",
        default=22.0,
        min_value=5.0,
        max_value=150.0,
        unit="m/s",
        description="highest airspeed the autopilot commands",
    ),
    ParamSpec(
        name="FW_R_LIM",
        default=35.0,
        min_value=5.0,
        max_value=65.0,
        unit="deg",
        description="bank angle limit",
    ),
    ParamSpec(
        name="FW_P_LIM_MAX",
        default=30.0,
        min_value=0.0,
        max_value=60.0,
        unit="deg",
        description="maximum pitch (nose up)",
    ),
    ParamSpec(
        name="FW_P_LIM_MIN",
        default=-30.0,
        min_value=-60.0,
        max_value=0.0,
        unit="deg",
        description="minimum pitch (nose down)",
    ),
    ParamSpec(
        name="FW_T_CLMB_MAX",
        default=3.0,
        min_value=0.5,
        max_value=15.0,
        unit="m/s",
        description="maximum climb rate the height loop demands",
    ),
    ParamSpec(
        name="FW_T_SINK_MAX",
        default=4.0,
        min_value=0.5,
        max_value=15.0,
        unit="m/s",
        description="maximum sink rate the height loop demands",
    ),
    ParamSpec(
        name="FW_CLMBOUT_DIFF",
        default=10.0,
        min_value=0.0,
        max_value=150.0,
        unit="m",
        description="take-off: climb wings level until this close to the take-off altitude",
    ),
    ParamSpec(
        name="FW_LND_ANG",
        default=6.0,
        min_value=1.0,
        max_value=15.0,
        unit="deg",
        description="landing glide slope",
    ),
    ParamSpec(
        name="FW_LND_AIRSPD",
        default=13.0,
        min_value=6.0,
        max_value=100.0,
        unit="m/s",
        description="landing approach airspeed",
    ),
    ParamSpec(
        name="NAV_L1_PERIOD",
        default=16.0,
        min_value=5.0,
        max_value=50.0,
        unit="s",
        description="L1 path-following period (smaller is tighter)",
    ),
    ParamSpec(
        name="NAV_L1_DAMPING",
        default=0.75,
        min_value=0.6,
        max_value=0.9,
        description="L1 path-following damping ratio",
    ),
    ParamSpec(
        name="NAV_ACC_RAD",
        default=10.0,
        min_value=0.05,
        max_value=200.0,
        unit="m",
        description="waypoint acceptance radius when the item gives none",
    ),
    ParamSpec(
        name="NAV_FW_ALT_RAD",
        default=10.0,
        min_value=0.05,
        max_value=200.0,
        unit="m",
        description="altitude acceptance (take-off, loiter to altitude, capture start)",
    ),
    ParamSpec(
        name="NAV_LOITER_RAD",
        default=80.0,
        min_value=25.0,
        max_value=1000.0,
        unit="m",
        description="loiter radius when the item gives none (hold, RTL, end of mission)",
    ),
    ParamSpec(
        name="MIS_TAKEOFF_ALT",
        default=30.0,
        min_value=5.0,
        max_value=500.0,
        unit="m",
        description="take-off altitude above home for a take-off command without one",
    ),
    ParamSpec(
        name="RTL_RETURN_ALT",
        default=60.0,
        min_value=10.0,
        max_value=1500.0,
        unit="m",
        description="return altitude above home (RTL climbs to it, never descends to it)",
    ),
    ParamSpec(
        name="COM_POS_FS_EPH",
        default=5.0,  # PX4's default
        min_value=1.0,
        max_value=10000.0,
        unit="m",
        description="position failsafe: horizontal position uncertainty (1-sigma) above which "
        "the onboard estimate is no longer trusted (COM_POS_FS_ACT acts)",
    ),
    ParamSpec(
        name="COM_POS_FS_ACT",
        default=0.0,
        min_value=0.0,
        max_value=2.0,
        is_int=True,
        description="position failsafe action: 0 continue the mission and warn, 1 loiter "
        "(hold), 2 return to launch (numbered as PX4's NAV_DLL_ACT)",
    ),
    ParamSpec(
        name="EKF2_GPS_CTRL",
        default=7.0,
        min_value=0.0,
        max_value=15.0,
        is_int=True,
        description="GNSS aiding bits (PX4): bit 0 horizontal position; 0 keeps the receiver's "
        "fixes (position and velocity) out of the onboard filter",
    ),
    ParamSpec(
        name="EKF2_EV_CTRL",
        default=0.0,
        min_value=0.0,
        max_value=15.0,
        is_int=True,
        description="external vision aiding bits (PX4): bit 0 horizontal position "
        "(VISION_POSITION_ESTIMATE, ODOMETRY); on by default with serve --nav-aid mavlink",
    ),
    ParamSpec(
        name="EKF2_EV_NOISE_MD",
        default=0.0,
        min_value=0.0,
        max_value=1.0,
        is_int=True,
        description="external vision noise: 0 the message's covariance (EKF2_EVP_NOISE "
        "without one), 1 always EKF2_EVP_NOISE",
    ),
    ParamSpec(
        name="EKF2_EVP_NOISE",
        default=5.0,
        min_value=0.01,
        max_value=1000.0,
        unit="m",
        description="1-sigma of an aid position without covariance (--nav-aid-sigma)",
    ),
)

PARAMS = PARAMS + tuple(
    ParamSpec(
        name=name,
        default=float(default),
        min_value=-(2.0**31) if is_int else -1e9,
        max_value=2.0**31 - 1 if is_int else 1e9,
        is_int=is_int,
        unit=unit,
        description=description,
    )
    for name, default, is_int, unit, description in PX4_CONNECT_PARAMS
)

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
        """Airspeed within [FW_AIRSPD_MIN, FW_AIRSPD_MAX]."""
        return min(self.max_m_s, max(self.min_m_s, speed_m_s))
