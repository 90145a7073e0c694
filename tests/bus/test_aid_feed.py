"""BusAidFeed: the estimates of ``--nav-aid NAME`` as measurements for the onboard filter."""

from __future__ import annotations

from air_sitl.bus.aid_feed import BusAidFeed
from air_sitl.bus.codec import Estimate
from air_sitl.state import GeoPoint


def _est(frame: int, east: float = 1.0) -> Estimate:
    return Estimate(frame=frame, sim_time_ns=None, enu_m=(east, 2.0, 3.0), geo=None)


def test_in_lockstep_frame_k_is_released_once_frame_k_plus_lag_is_out() -> None:
    times = {k: 1_000 + 20 * k for k in range(10)}
    feed = BusAidFeed("mm", lockstep_lag=1, time_of=times.get)
    for k in (2, 0, 1):  # arrival order does not matter
        feed.on_estimate("mm", k, None, _est(k))
    feed.on_estimate("other", 0, 5, _est(0))  # another estimator: ignored
    assert feed.take(frames_submitted=1) == []  # only frame 0 out: nothing guaranteed yet
    first = feed.take(frames_submitted=2)  # frame 1 out: frame 0's estimate is due
    assert [m.sim_time_ns for m in first] == [1_000]
    rest = feed.take(frames_submitted=10)
    assert [m.sim_time_ns for m in rest] == [1_020, 1_040]  # in frame order, timed by frame
    assert all(m.frame == "enu" and m.position == (1.0, 2.0, 3.0) for m in rest)


def test_without_lockstep_everything_is_taken_and_odd_payloads_pass_through() -> None:
    feed = BusAidFeed("mm")
    feed.on_estimate("mm", None, 7, None)  # refused by the codec: invalid for the filter
    geo = GeoPoint(lat_deg=1.0, lon_deg=2.0, alt_amsl_m=3.0)
    feed.on_estimate("mm", None, 8, Estimate(frame=None, sim_time_ns=8, enu_m=None, geo=geo))
    feed.on_estimate("mm", None, 9, Estimate(frame=None, sim_time_ns=9, enu_m=None, geo=None))
    a, b, c = feed.take(frames_submitted=0)
    assert a.position == ("invalid",)  # type: ignore[comparison-overlap]
    assert b.frame == "wgs84" and b.position == (1.0, 2.0, 3.0)
    assert c.position is None  # "no estimate": counted as empty
    assert feed.take(frames_submitted=0) == []
