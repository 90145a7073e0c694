"""Bad external-aid input is rejected and counted, never raises, never touches the state."""

from __future__ import annotations

import math

import pytest

from air_sitl.nav import AidMeasurement, AidResult
from air_sitl.nav.types import BaroSample
from air_sitl.state import GpsFix
from tests.nav.synthetic import NS, Straight, truth_ned


def good(t_ns: int, name: str = "map", **kw: object) -> AidMeasurement:
    n, e, d = truth_ned(t_ns)
    return AidMeasurement(name=name, sim_time_ns=t_ns, position=(e, n, -d), **kw)  # type: ignore[arg-type]


class AidedStraight(Straight):
    """GNSS for 10 s, then only a 20 Hz aid at the truth; ``extra(t)`` adds more input."""

    def __init__(self, extra=None) -> None:  # type: ignore[no-untyped-def]
        super().__init__()
        self.extra = extra
        self.results: list[AidResult] = []

    def step(self) -> None:
        t = self.t_ns
        if t >= 10 * NS:
            self.gnss = False
            if t % 50_000_000 == 0:
                self.nav.fuse_aid(good(t), t)
            if self.extra is not None:
                for m in self.extra(t):
                    self.results.append(self.nav.fuse_aid(m, t))
        super().step()


BAD_AT_NS = 12 * NS + 25_000_000  # between two good measurements


def _bad_inputs(t: int) -> list[AidMeasurement]:
    if t != BAD_AT_NS:
        return []
    n, e, d = truth_ned(t)
    return [
        AidMeasurement(name="map", sim_time_ns=t, position=(math.nan, n, -d)),
        AidMeasurement(name="map", sim_time_ns=t, position=(math.inf, n, -d)),
        AidMeasurement(name="map", sim_time_ns=t, position=(1.0, 2.0)),  # type: ignore[arg-type]
        AidMeasurement(name="map", sim_time_ns=t, position="east"),  # type: ignore[arg-type]
        AidMeasurement(name="map", sim_time_ns=t, position=(e, n, -d), sigma_m=-1.0),
        AidMeasurement(name="map", sim_time_ns=t, position=(e, n, -d), sigma_m=math.nan),
        AidMeasurement(name="map", sim_time_ns=t, position=(e, n, -d), cov_m2=(1.0,) * 9),
        AidMeasurement(name="map", sim_time_ns=t, position=(e, n, -d), cov_m2=(math.nan,) * 9),
        AidMeasurement(name="map", sim_time_ns=t, position=(e, n, -d), frame="ecef"),
        AidMeasurement(name="map", sim_time_ns=t + NS, position=(e, n, -d)),  # future
        AidMeasurement(name="map", sim_time_ns=t - 2 * NS, position=(e, n, -d)),  # far past
        AidMeasurement(name="map", sim_time_ns=1.5, position=(e, n, -d)),  # type: ignore[arg-type]
        AidMeasurement(name="map", sim_time_ns=t, position=(90.5, 0.0, 0.0), frame="wgs84"),
        AidMeasurement(name="map", sim_time_ns=t, position=None),  # empty
        AidMeasurement(name="map", sim_time_ns=t, position=(math.nan,) * 3),  # empty
        AidMeasurement(name="map", sim_time_ns=t, position=(None, None, None)),  # type: ignore[arg-type]
        AidMeasurement(name="map", sim_time_ns=t, position=(e + 200.0, n, -d)),  # a jump
    ]


@pytest.fixture(scope="module")
def clean() -> AidedStraight:
    run = AidedStraight()
    run.run(16.0)
    return run


@pytest.fixture(scope="module")
def dirty() -> AidedStraight:
    run = AidedStraight(_bad_inputs)
    run.run(16.0)
    return run


@pytest.fixture
def aided() -> AidedStraight:
    """Two seconds on the aid alone (GNSS cut at 10 s): a filter to feed input to by hand."""
    run = AidedStraight()
    run.run(12.0)
    return run


def test_each_bad_input_has_its_verdict(dirty: AidedStraight) -> None:
    R = AidResult
    assert dirty.results == [
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_FRAME,
        R.REJECTED_FUTURE,
        R.REJECTED_STALE,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.EMPTY,
        R.EMPTY,
        R.EMPTY,
        R.ACCEPTED,  # the jump: accepted on arrival, gated at its time
    ]


def test_bad_input_counted(dirty: AidedStraight, clean: AidedStraight) -> None:
    d = dirty.nav.status().aids[0]
    c = clean.nav.status().aids[0]
    assert d.received == c.received + 17
    assert d.empty == 3 and c.empty == 0
    assert d.fused == c.fused
    assert d.rejected == 14 and c.rejected == 0
    assert d.rejected_by_reason == {
        "invalid": 10,
        "frame": 1,
        "future": 1,
        "stale": 1,
        "gate": 1,
    }
    assert d.resets == 0


def test_bad_input_does_not_touch_the_state(dirty: AidedStraight, clean: AidedStraight) -> None:
    assert dirty.nav.estimate() == clean.nav.estimate()
    assert (dirty.nav.ekf.P == clean.nav.ekf.P).all()


def test_flood_rejected_by_rate() -> None:
    """A 1 kHz flood (stamped 1 ms apart, at the truth) for 1 s: at most 100 Hz get through,
    the rest are counted as rate rejections; the estimate stays on the truth."""

    def flood(t: int):  # type: ignore[no-untyped-def]
        if 12 * NS <= t < 13 * NS:
            return [good(t + k * 1_000_000, name="flood") for k in range(-4, 1)]
        return []

    run = AidedStraight(flood)
    run.run(14.0)
    aid = next(a for a in run.nav.status().aids if a.name == "flood")
    assert aid.received == 1000
    assert aid.rejected_by_reason.get("rate", 0) >= 890
    assert aid.fused + aid.rejected + aid.empty == aid.received
    assert run.error_m() < 1.0


def test_horizon_bounds(aided: AidedStraight) -> None:
    now = aided.t_ns
    nav = aided.nav
    assert nav.fuse_aid(good(now - 600_000_000, "late"), now) is AidResult.REJECTED_STALE
    assert nav.fuse_aid(good(now - 490_000_000, "late"), now) is AidResult.ACCEPTED
    assert nav.fuse_aid(good(now - 495_000_000, "late"), now) is AidResult.REJECTED_ORDER
    assert nav.fuse_aid(good(now - 485_000_000, "late"), now) is AidResult.REJECTED_RATE
    assert nav.fuse_aid(good(now + 1, "late"), now) is AidResult.REJECTED_FUTURE


def test_other_frames_and_covariance_are_used() -> None:
    from air_sitl.frames import ned2geodetic
    from tests.nav.synthetic import HOME

    def other(t: int):  # type: ignore[no-untyped-def]
        if t >= 10 * NS and t % 50_000_000 == 25_000_000:
            n, e, d = truth_ned(t)
            lat, lon, alt = ned2geodetic(n, e, d, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
            kind = (t // 50_000_000) % 3
            if kind == 0:
                return [AidMeasurement(name="ned", sim_time_ns=t, position=(n, e, d), frame="ned")]
            if kind == 1:
                return [
                    AidMeasurement(
                        name="geo", sim_time_ns=t, position=(lat, lon, alt), frame="wgs84"
                    )
                ]
            cov = (16.0, 2.0, 0.0, 2.0, 9.0, 0.0, 0.0, 0.0, 25.0)
            return [AidMeasurement(name="cov", sim_time_ns=t, position=(e, n, -d), cov_m2=cov)]
        return []

    run = AidedStraight(other)
    run.run(16.0)
    for aid in run.nav.status().aids:
        assert aid.rejected == 0, aid
        assert aid.fused > 30, aid
    assert run.error_m() < 0.5


def test_gnss_and_baro_bad_input_counted() -> None:
    run = Straight()
    run.run(5.0)
    t = run.t_ns
    nav = run.nav
    base = dict(
        sim_time_ns=t,
        alt_amsl_m=200.0,
        vel_ned_m_s=(15.0, 0.0, 0.0),
        satellites=14,
        eph_m=1.5,
        epv_m=3.0,
    )
    assert not nav.fuse_gnss(GpsFix(lat_deg=math.nan, lon_deg=0.0, fix_type=3, **base), t)
    assert not nav.fuse_gnss(GpsFix(lat_deg=38.5, lon_deg=-121.5, fix_type=0, **base), t)
    assert not nav.fuse_baro(BaroSample(sim_time_ns=t, alt_amsl_m=math.inf), t)
    status = nav.status()
    assert status.gnss.rejected_by_reason == {"invalid": 1}
    assert status.gnss.empty == 1
    assert status.baro.rejected_by_reason == {"invalid": 1}
    run.run(1.0)
    assert run.error_m() < 0.5


def test_odd_types_never_raise(aided: AidedStraight) -> None:
    import numpy as np

    nav, t = aided.nav, aided.t_ns
    n, e, d = truth_ned(t)
    odd = [
        AidMeasurement(name="x", sim_time_ns=np.int64(t), position=np.array([e, n, -d])),  # type: ignore[arg-type]
        AidMeasurement(name="y", sim_time_ns=t, position=(e, n, -d), cov_m2=np.eye(3) * 4.0),  # type: ignore[arg-type]
        AidMeasurement(name="z", sim_time_ns=t, position=np.full(3, np.nan)),  # type: ignore[arg-type]
        AidMeasurement(name="w", sim_time_ns=t, position=(e, n, -d), frame=["enu"]),  # type: ignore[arg-type]
        AidMeasurement(name="v", sim_time_ns=True, position=(e, n, -d)),
        AidMeasurement(name=3, sim_time_ns=t, position=(e, n, -d), sigma_m="5"),  # type: ignore[arg-type]
        None,
        "garbage",
    ]
    results = [nav.fuse_aid(m, t) for m in odd]  # type: ignore[arg-type]
    R = AidResult
    assert results == [
        R.ACCEPTED,
        R.ACCEPTED,
        R.EMPTY,
        R.REJECTED_FRAME,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
        R.REJECTED_INVALID,
    ]
    aided.run(1.0)
    assert aided.error_m() < 0.5


def test_baro_step_rejected_then_reset_after_timeout() -> None:
    """A 100 m barometer step without GNSS (the only height source): gated, then after 5 s
    of rejection the height follows it. (With GNSS the offset calibration absorbs it.)"""
    from tests.nav.synthetic import HEIGHT_M

    run = Straight()
    run.run(10.0)
    run.gnss = False
    run.baro_offset_m = 100.0
    run.run(4.0)
    assert abs(-run.nav.estimate().pos_ned_m[2] - HEIGHT_M) < 2.0
    run.run(3.0)
    assert abs(-run.nav.estimate().pos_ned_m[2] - HEIGHT_M - 100.0) < 2.0
    baro = run.nav.status().baro
    assert baro.resets == 1 and baro.rejected >= 45
