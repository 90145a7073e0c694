"""The filter in the loop (``--nav ekf``) on real flights: the autopilot flies on the estimate.

In-process flights through the builder (air start, no camera); aids come from a test feed that
reads the truth of the flight it aids (truth + offset + noise), so each case is a few seconds.
"""

from __future__ import annotations

import itertools
import math
import statistics
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from air_sitl.builder import build_flight, load_setup
from air_sitl.fdm.base import Wind
from air_sitl.nav import AidMeasurement
from air_sitl.options import OPEN_END_NS, FlightOptions
from air_sitl.runner import Flight
from air_sitl.state import SimSample

MISSIONS = Path(__file__).resolve().parents[2] / "missions"
NS = 1_000_000_000


def flight_of(
    plan: str = "UC-200", *, nav: str = "ekf", deny_after_s: float | None = None, seed: int = 1
) -> Flight:
    denied = () if deny_after_s is None else ((round(deny_after_s * NS), OPEN_END_NS),)
    options = FlightOptions(
        air_start=True,
        nav=nav,
        wind=Wind(speed_m_s=5.0, from_deg=270.0),
        seed=seed,
        gps_denied_ns=denied,
        nav_aid="aid",
    )
    return build_flight(load_setup(MISSIONS / f"{plan}.plan", options))


@dataclass
class TruthFeed:
    """A 10 Hz aid: the flight's truth + ``offset_ne_m`` + N(0, sigma), from ``start_s``;
    ``bad`` maps a time (s) to a measurement to send instead."""

    flight: Flight
    start_s: float
    offset_ne_m: tuple[float, float] = (0.0, 0.0)
    sigma_m: float = 3.0
    bad: dict[float, AidMeasurement] = field(default_factory=dict)
    rng: np.random.Generator = field(default_factory=lambda: np.random.default_rng(5))

    def take(self, frames_submitted: int) -> list[AidMeasurement]:
        s = self.flight.state
        assert s is not None
        t = s.sim_time_ns
        if t < self.start_s * NS or t % 100_000_000:
            return []
        key = round(t / NS, 1)
        if key in self.bad:
            return [self.bad[key]]
        n, e, d = s.pos_ned_m
        z = self.rng.standard_normal(2) * self.sigma_m
        east = e + self.offset_ne_m[1] + z[1]
        north = n + self.offset_ne_m[0] + z[0]
        return [
            AidMeasurement(
                name="aid", sim_time_ns=t, position=(east, north, -d), sigma_m=self.sigma_m
            )
        ]


def run(
    flight: Flight, seconds: float, every_s: float = 1.0
) -> tuple[dict[str, Any], list[SimSample]]:
    trace: list[SimSample] = []
    period = round(every_s * NS)

    def keep(sample: SimSample) -> bool:
        if sample.state.sim_time_ns % period == 0:
            trace.append(sample)
        return False

    result = flight.run(stop=keep, max_sim_time_ns=round(seconds * NS))
    return result.summary, trace


def error_ne(sample: SimSample) -> tuple[float, float]:
    assert sample.nav is not None
    return (
        sample.nav.pos_ned_m[0] - sample.state.pos_ned_m[0],
        sample.nav.pos_ned_m[1] - sample.state.pos_ned_m[1],
    )


def test_with_gnss_the_autopilot_flies_on_an_estimate_within_3_m() -> None:
    summary, trace = run(flight_of(), 150.0)
    nav = summary["nav"]
    assert nav["source"] == "ekf"
    assert nav["horizontal_error_m"]["p95"] <= 3.0, nav
    assert nav["horizontal_error_denied_m"] is None and nav["gnss_denied_s"] == 0.0
    keys = ("name", "received", "fused", "rejected", "empty")
    assert {k: nav["aid"][k] for k in keys} == {
        "name": "aid", "received": 0, "fused": 0, "rejected": 0, "empty": 0
    }  # fmt: skip
    assert summary["truth_max_cross_track_m"] is not None
    assert summary["truth_max_cross_track_m"] < 10.0
    assert all(s.nav is not None for s in trace[2:])
    # The estimate is not the truth (the autopilot flies on noisy sensors).
    assert any(math.hypot(*error_ne(s)) > 0.01 for s in trace[2:])


def test_every_extra_sensor_reading_reaches_the_filter() -> None:
    # The loop asks the barometer (20 Hz), airspeed sensor and compass (10 Hz) only at
    # multiples of their common period: not one reading may be skipped.
    flight = flight_of()
    times: list[int] = []

    def keep(sample: SimSample) -> bool:
        times.append(sample.state.sim_time_ns)
        return False

    flight.run(stop=keep, max_sim_time_ns=10 * NS)
    assert flight.nav is not None
    f = flight.nav.filter
    counts = (f.baro.counters.received, f.airspeed.counters.received, f.mag.counters.received)
    expected = tuple(sum(1 for t in times if t % (ms * 1_000_000) == 0) for ms in (50, 100, 100))
    assert len(times) >= 1999 and counts == expected


@pytest.mark.parametrize("wanted", [False, True])
def test_status_snapshots_at_5_hz_only_for_a_reader(wanted: bool) -> None:
    flight = flight_of()
    assert flight.nav is not None
    flight.nav.status_wanted = wanted  # what the MAVLink endpoint sets (ESTIMATOR_STATUS)
    seen: set[int] = set()

    def keep(sample: SimSample) -> bool:
        status = flight.nav.last_status if flight.nav is not None else None
        if status is not None:
            seen.add(status.sim_time_ns)
        return False

    flight.run(stop=keep, max_sim_time_ns=3 * NS)
    if not wanted:
        assert seen == set()
    else:
        times = sorted(seen)
        assert len(times) >= 10 and {b - a for a, b in itertools.pairwise(times)} == {NS // 5}


def test_nav_truth_reports_the_same_keys_without_errors() -> None:
    summary, trace = run(flight_of(nav="truth"), 20.0)
    assert summary["nav"] == {
        "source": "truth",
        "horizontal_error_m": None,
        "horizontal_error_denied_m": None,
        "gnss_denied_s": 0.0,
        "aid": None,
    }
    assert summary["truth_max_cross_track_m"] == summary["max_cross_track_m"]
    assert all(s.nav is None for s in trace)


def test_denial_without_aid_drifts_and_keeps_flying() -> None:
    summary, trace = run(flight_of(deny_after_s=30.0), 200.0)
    nav = summary["nav"]
    assert nav["gnss_denied_s"] == pytest.approx(170.0, abs=2.0)
    denied = nav["horizontal_error_denied_m"]
    assert denied is not None and denied["max"] > 3.0, nav  # it drifts ...
    assert nav["final_horizontal_error_m"] > 2.0
    assert any("GNSS lost" in e for e in nav["events"])
    # ... the uncertainty grows, the aircraft keeps flying its circle at altitude.
    stds = [s.nav.std_h_m for s in trace if s.nav is not None]
    assert stds[-1] > 5 * stds[25]
    assert all(not s.state.on_ground and s.state.alt_agl_m > 150.0 for s in trace)
    assert summary["sim_time_s"] == pytest.approx(200.0)


def test_position_failsafe_rtl_by_parameter() -> None:
    flight = flight_of(deny_after_s=20.0)
    flight.autopilot.params.set("COM_POS_FS_ACT", 2)
    summary, trace = run(flight, 120.0)
    assert summary["nav"]["failsafes"] == 1
    assert any("return to launch" in e for e in summary["nav"]["events"])
    assert trace[-1].autopilot.mode.value == "rtl"


def test_an_aid_during_denial_holds_the_estimate() -> None:
    flight = flight_of(deny_after_s=30.0)
    flight.nav.aid_feed = TruthFeed(flight, start_s=25.0)  # type: ignore[union-attr]
    summary, _trace = run(flight, 200.0)
    nav = summary["nav"]
    assert nav["aid"]["fused"] > 1000 and nav["aid"]["rejected"] < 20, nav["aid"]
    assert nav["horizontal_error_denied_m"]["p95"] < 5.0, nav
    assert summary["truth_max_cross_track_m"] < 10.0


def test_an_aid_biased_40_m_east_moves_the_flown_track_40_m_west() -> None:
    flight = flight_of("FL-200", deny_after_s=40.0)
    flight.nav.aid_feed = TruthFeed(flight, start_s=40.0, offset_ne_m=(0.0, 40.0))  # type: ignore[union-attr]
    summary, trace = run(flight, 160.0)
    late = [error_ne(s) for s in trace if s.state.sim_time_ns >= 80 * NS]
    east = statistics.fmean(e for _, e in late)
    north = statistics.fmean(n for n, _ in late)
    # The filter first rejects the jump, then (5 s of rejections, the only source) resets to
    # the aid: it believes itself 40 m east of where it is, so the aircraft flies 40 m west.
    assert east == pytest.approx(40.0, abs=6.0), (east, north)
    assert abs(north) < 6.0
    assert summary["nav"]["aid"]["resets"] >= 1, summary["nav"]["aid"]


def test_bad_aid_inputs_are_rejected_counted_and_harmless() -> None:
    flight = flight_of(deny_after_s=30.0)
    nan = math.nan

    def m(t_s: float, **kw: object) -> AidMeasurement:
        base = {"name": "aid", "sim_time_ns": round(t_s * NS), "position": (0.0, 0.0, 200.0)}
        base.update(kw)
        return AidMeasurement(**base)  # type: ignore[arg-type]

    bad = {
        40.0: m(40.0, position=(nan, 1.0, 2.0)),  # NaN among numbers: invalid
        41.0: m(41.0, sim_time_ns=round(45.0 * NS)),  # from the future
        42.0: m(42.0, sim_time_ns=round(30.0 * NS)),  # far behind the fusion horizon
        43.0: m(43.0, frame="ecef"),  # unknown frame
        44.0: m(44.0, cov_m2=(1.0,) * 9),  # singular covariance: invalid
        45.0: m(45.0, position=None),  # no position: empty, not rejected
    }
    feed = TruthFeed(flight, start_s=25.0, bad=bad)
    flight.nav.aid_feed = feed  # type: ignore[union-attr]
    jump_t = [50.0 + 0.1 * k for k in range(10)]  # 1 s of a 200 m jump: gated out
    for t in jump_t:
        feed.bad[round(t, 1)] = None  # type: ignore[assignment]

    def take(frames_submitted: int) -> list[AidMeasurement]:
        s = flight.state
        assert s is not None
        key = round(s.sim_time_ns / NS, 1)
        out = TruthFeed.take(feed, frames_submitted)
        if key in feed.bad and feed.bad[key] is None and s.sim_time_ns % 100_000_000 == 0:
            n, e, d = s.pos_ned_m
            return [m(key, position=(e + 200.0, n, -d), sigma_m=3.0)]
        if key == 60.0 and s.sim_time_ns % 100_000_000 == 0:
            # A flood: 100 measurements at one instant (1 kHz for 0.1 s).
            return out + [m(key, sim_time_ns=s.sim_time_ns - k * 1_000_000) for k in range(1, 100)]
        return out

    feed.take = take  # type: ignore[method-assign]
    summary, _trace = run(flight, 90.0)
    aid = summary["nav"]["aid"]
    reasons = aid["rejected_by_reason"]
    for reason in ("invalid", "future", "stale", "frame", "gate"):
        assert reasons.get(reason, 0) >= 1, reasons
    assert reasons.get("order", 0) + reasons.get("rate", 0) >= 90, reasons
    assert aid["empty"] == 1
    assert aid["received"] >= aid["fused"] + aid["rejected"] + aid["empty"]
    assert summary["nav"]["horizontal_error_denied_m"]["max"] < 10.0, summary["nav"]
