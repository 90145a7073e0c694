"""ParamStore: PX4 names, defaults, validation, stable MAVLink index order."""

from __future__ import annotations

import math

import pytest

from air_sitl.autopilot.executor import MissionExecutor
from air_sitl.autopilot.params import PARAMS, ParamError, ParamStore
from air_sitl.errors import AirSitlError

from .sim import KinematicPlane, mission, wp


def test_defaults_and_px4_names() -> None:
    p = ParamStore()
    assert p.get("FW_AIRSPD_TRIM") == 15.0
    assert p.get("FW_R_LIM") == 35.0
    assert p.get("NAV_LOITER_RAD") == 80.0
    for name in ("FW_AIRSPD_MIN", "FW_AIRSPD_MAX", "FW_P_LIM_MAX", "FW_P_LIM_MIN", "NAV_ACC_RAD",
                 "NAV_L1_PERIOD", "RTL_RETURN_ALT", "FW_CLMBOUT_DIFF", "FW_T_CLMB_MAX",
                 "FW_T_SINK_MAX", "MIS_TAKEOFF_ALT"):  # fmt: skip
        assert name in p.names()
    for spec in PARAMS:
        assert spec.min_value <= spec.default <= spec.max_value, spec.name
        assert len(spec.name) <= 16, "MAVLink param_id holds 16 characters"


def test_index_order_is_stable_and_complete() -> None:
    p = ParamStore()
    names = p.names()
    assert names == tuple(spec.name for spec in PARAMS)
    assert p.count() == len(names) == len(set(names))
    assert [p.index(n) for n in names] == list(range(len(names)))
    assert [name for name, _ in p.items()] == list(names)


def test_set_validates_and_counts_versions() -> None:
    p = ParamStore()
    v0 = p.version
    assert p.set("FW_R_LIM", 20) == 20.0
    assert p.get("FW_R_LIM") == 20.0
    assert p.version == v0 + 1
    p.set("FW_R_LIM", 20.0)  # no change, no new version
    assert p.version == v0 + 1
    # As PX4: a set outside the range is stored; the controller clamps what it uses.
    assert p.set("FW_R_LIM", 99.0) == 99.0
    assert p.in_range("FW_R_LIM") == 65.0
    p.set("FW_R_LIM", 20.0)
    with pytest.raises(ParamError, match="FW_R_LIM"):
        p.set("FW_R_LIM", math.nan)
    with pytest.raises(ParamError, match="NO_SUCH"):
        p.set("NO_SUCH", 1.0)
    with pytest.raises(ParamError, match="NO_SUCH"):
        p.get("NO_SUCH")
    assert p.get("FW_R_LIM") == 20.0  # failed sets change nothing
    assert issubclass(ParamError, AirSitlError)


def test_overrides_in_constructor_are_validated() -> None:
    assert ParamStore({"NAV_LOITER_RAD": 150.0}).get("NAV_LOITER_RAD") == 150.0
    with pytest.raises(ParamError):
        ParamStore({"NAV_LOITER_RAD": 1.0})


def test_changes_take_effect_in_flight() -> None:
    """The executor re-reads the store: a lower bank limit caps the next bank command."""
    params = ParamStore()
    m = mission(wp(0, 0, 100), wp(0, 2000, 100))
    ex = MissionExecutor(m, m.planned_home, params)  # type: ignore[arg-type]
    # Flying the wrong way along the leg: guidance asks for a full-bank turn.
    plane = KinematicPlane(n=20.0, e=500.0, alt_rel=100.0, course_rad=-math.pi / 2, airspeed=15.0)
    ex.air_start(plane.state())
    assert abs(ex.update(plane.state()).target.roll_rad) == pytest.approx(math.radians(35.0))
    params.set("FW_R_LIM", 20.0)
    assert abs(ex.update(plane.state()).target.roll_rad) == pytest.approx(math.radians(20.0))
    params.set("FW_R_LIM", 80.0)  # stored as sent; never flown beyond the range's top, 65
    assert math.radians(20.0) < abs(ex.update(plane.state()).target.roll_rad) <= math.radians(65)
