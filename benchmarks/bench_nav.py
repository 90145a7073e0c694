"""Cost and accuracy of the navigation filter (air_sitl.nav) on recorded JSBSim flights.

Usage: python benchmarks/bench_nav.py [--scenarios UC-200,FL-200,FR-200] [--seconds 240]
                                      [--cost-only]

Cost: the filter fed as a flight will feed it (IMU 200 Hz, GNSS 5 Hz, baro 20 Hz, airspeed and
compass 10 Hz; then the same with GNSS denied and a 20 Hz position aid), in microseconds per
200 Hz step of process CPU time (the machine is shared), beside floors measured in the same
run: a bare loop over the same steps calling one no-op function per step, and the same feeding
of a filter whose methods do nothing. Accuracy: horizontal error p95 and mean NEES with GNSS,
and the dead-reckoning error 60 s and 120 s after GNSS is cut at 60 s.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO))  # the recorded-flight helpers live with the nav tests


def _best_of(n: int, fn) -> float:  # type: ignore[no-untyped-def]
    best = math.inf
    for _ in range(n):
        t0 = time.process_time()
        fn()
        best = min(best, time.process_time() - t0)
    return best


def cost(scenario: str, seconds: float) -> None:
    import numpy as np

    from air_sitl.nav import NavFilter
    from tests.nav.flights import enu_aid, feed, record

    rec = record(scenario, seconds)
    steps = rec.steps
    n = len(steps)

    def noop(nav: object, step: object, gnss: bool = True) -> None:
        return None

    def bare() -> None:
        nav = None
        for s in steps:
            noop(nav, s)

    class NullFilter:
        """The filter's API doing nothing: the call overhead of feeding it."""

        def predict(self, imu: object) -> None: ...
        def fuse_gnss(self, fix: object, now_ns: int | None = None) -> None: ...
        def fuse_baro(self, sample: object, now_ns: int | None = None) -> None: ...
        def fuse_airspeed(self, sample: object, now_ns: int | None = None) -> None: ...
        def fuse_heading(self, sample: object, now_ns: int | None = None) -> None: ...

    def null() -> None:
        nav = NullFilter()
        for s in steps:
            feed(nav, s)  # type: ignore[arg-type]

    def full() -> None:
        nav = NavFilter(rec.home)
        for s in steps:
            feed(nav, s)

    def imu_only() -> None:
        nav = NavFilter(rec.home)
        for s in steps:
            nav.predict(s.imu)

    rng = np.random.default_rng(1)
    noise = rng.standard_normal((n, 2)) * 5.0
    half = n // 4
    aids = [
        enu_aid(
            "map",
            s.imu.sim_time_ns,
            s.state.pos_ned_m[0] + noise[i, 0],
            s.state.pos_ned_m[1] + noise[i, 1],
            sigma=5.0,
        )
        if i >= half and i % 10 == 0
        else None
        for i, s in enumerate(steps)
    ]

    def denied_with_aid() -> None:
        nav = NavFilter(rec.home)
        for i, s in enumerate(steps):
            m = aids[i]
            if m is not None:
                nav.fuse_aid(m, m.sim_time_ns)
            feed(nav, s, gnss=i < half)

    t_bare = _best_of(5, bare)
    t_null = _best_of(5, null)
    t_full = _best_of(3, full)
    t_imu = _best_of(3, imu_only)
    t_aid = _best_of(3, denied_with_aid)
    us = 1e6 / n
    print(f"cost on {scenario}, {n} steps of 5 ms (best of 3):")
    print(f"  bare loop (one no-op call per step)     {t_bare * us:6.2f} us/step")
    print(
        f"  feeding a filter that does nothing      {t_null * us:6.2f} us/step"
        f"  = {t_null / t_bare:5.1f}x bare"
    )
    print(
        f"  IMU prediction only                     {t_imu * us:6.2f} us/step"
        f"  = {t_imu / t_bare:5.1f}x bare"
    )
    print(
        f"  IMU + GNSS + baro + airspeed + compass  {t_full * us:6.2f} us/step"
        f"  = {t_full / t_bare:5.1f}x bare"
    )
    print(
        f"  same, GNSS denied after 1/4, 20 Hz aid  {t_aid * us:6.2f} us/step"
        f"  = {t_aid / t_bare:5.1f}x bare"
    )


def accuracy(scenario: str, seconds: float) -> None:
    from tests.nav.flights import at, between, fly, percentile, record

    rec = record(scenario, seconds)
    _, trace = fly(rec)
    kept = between(trace, 20.0, 1e9)
    errors = [p.error_h_m for p in kept]
    nees = []
    for p in kept:
        a, b, c = p.cov_ne_m2
        dn, de = p.error_ne_m
        nees.append((c * dn * dn - 2 * b * dn * de + a * de * de) / (a * c - b * b))
    _, denied = fly(rec, deny_after_s=60.0)
    drift = [at(denied, 60.0 + dt) for dt in (60.0, 120.0)]
    print(
        f"{scenario}: GNSS p95 {percentile(errors, 95):.2f} m, max {max(errors):.2f} m, "
        f"mean NEES {sum(nees) / len(nees):.2f} (chi2(2) expects 2); GNSS cut at 60 s: "
        + ", ".join(
            f"{p.t_s - 60.0:.0f} s later {p.error_h_m:.1f} m (std {p.std_h_m:.1f})" for p in drift
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="UC-200,FL-200,FR-200")
    parser.add_argument("--seconds", type=float, default=240.0)
    parser.add_argument("--cost-only", action="store_true")
    args = parser.parse_args()
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    cost(names[0], min(args.seconds, 120.0))
    if not args.cost_only:
        for name in names:
            accuracy(name, args.seconds)


if __name__ == "__main__":
    main()
