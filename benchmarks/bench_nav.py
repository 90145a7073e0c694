"""Cost and accuracy of the navigation filter (air_sitl.nav) on recorded JSBSim flights.

Usage: python benchmarks/bench_nav.py [--scenarios UC-200,FL-200,FR-200] [--seconds 240]
                                      [--cost-only] [--archive DIR ...]

Cost: the filter fed as a flight will feed it (IMU 200 Hz, GNSS 5 Hz, baro 20 Hz, airspeed and
compass 10 Hz; then the same with GNSS denied and a 20 Hz position aid), in microseconds per
200 Hz step of process CPU time (the machine is shared), beside floors measured in the same
run: a bare loop over the same steps calling one no-op function per step, and the same feeding
of a filter whose methods do nothing. Accuracy: horizontal error p95 and mean NEES with GNSS,
and the dead-reckoning error 60 s and 120 s after GNSS is cut at 60 s. ``--archive DIR``
(an archive written by fly/dataset: imu.csv, frames.csv, trajectory.csv) feeds the recorded
IMU from take-off and the recorded GNSS of the capture window (barometer, airspeed and compass
simulated from trajectory.csv) and scores the capture window, then the same with GNSS cut
for its second half.
"""

from __future__ import annotations

import argparse
import dataclasses
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


def archive(folder: Path) -> None:
    import csv
    from types import SimpleNamespace

    from air_sitl.frames import quat2euler
    from air_sitl.localize.archive import gnss_fix_of_row
    from air_sitl.nav import NavFilter
    from air_sitl.nav.sensors_extra import AirspeedSensor, Barometer, Magnetometer
    from air_sitl.state import GeoPoint, GpsFix, ImuSample
    from tests.nav.flights import percentile

    def rows(name: str) -> list[dict[str, str]]:
        with (folder / name).open(newline="") as f:
            return list(csv.DictReader(f))

    imu = rows("imu.csv")
    frames = rows("frames.csv")
    traj = rows("trajectory.csv")
    t0 = traj[0]
    home_ned = (float(t0["north_m"]), float(t0["east_m"]), float(t0["down_m"]))
    assert max(abs(x) for x in home_ned) < 1.0, "trajectory.csv does not start at home"
    home = GeoPoint(
        lat_deg=float(t0["lat_deg"]),
        lon_deg=float(t0["lon_deg"]),
        alt_amsl_m=float(t0["alt_amsl_m"]) + float(t0["down_m"]),
    )
    fixes: dict[int, GpsFix] = {}
    for r in frames:
        t = int(r["gps_time_ns"] or -1)
        if t >= 0 and t not in fixes and r["gps_fix_type"] == "3":
            fixes[t] = GpsFix(
                **dataclasses.asdict(gnss_fix_of_row(r)),  # time, position, velocity
                fix_type=3,
                satellites=int(r["gps_satellites"]),
                eph_m=float(r["gps_eph_m"]),
                epv_m=float(r["gps_epv_m"]),
            )
    truth = {
        int(r["sim_time_ns"]): (
            float(r["north_m"]),
            float(r["east_m"]),
            SimpleNamespace(
                sim_time_ns=int(r["sim_time_ns"]),
                alt_amsl_m=float(r["alt_amsl_m"]),
                airspeed_m_s=float(r["airspeed_m_s"]),
                yaw_rad=quat2euler(
                    (float(r["qw"]), float(r["qx"]), float(r["qy"]), float(r["qz"]))
                )[2],
            ),
        )
        for r in traj
    }
    capture = [int(r["sim_time_ns"]) for r in frames]
    c0, c1 = capture[0], capture[-1]
    last_fix = max((t for t in fixes if t <= c1), default=None)
    if last_fix is None or c1 - last_fix > 5 * 10**9:
        since = "the whole capture window" if last_fix is None else f"{last_fix / 1e9:.0f} s on"
        print(
            f"{folder.name}: frames.csv has no GNSS fix from {since} (GNSS denied in this "
            "flight?): the scores below dead-reckon there and do not say how the filter does "
            "with GNSS"
        )
    samples = [
        ImuSample(
            sim_time_ns=int(r["sim_time_ns"]),
            gyro_frd_rad_s=(float(r["gyro_x_rad_s"]), float(r["gyro_y_rad_s"]),
                            float(r["gyro_z_rad_s"])),
            accel_frd_m_s2=(float(r["accel_x_m_s2"]), float(r["accel_y_m_s2"]),
                            float(r["accel_z_m_s2"])),
            q_ahrs_body_to_ned_wxyz=(float(r["ahrs_qw"]), float(r["ahrs_qx"]),
                                     float(r["ahrs_qy"]), float(r["ahrs_qz"])),
        )
        for r in imu
    ]  # fmt: skip

    def run(deny_from_ns: int | None) -> list[tuple[int, float, float]]:
        nav = NavFilter(home)
        baro, tas, mag = Barometer(seed=0), AirspeedSensor(seed=0), Magnetometer(seed=0)
        out = []
        for s in samples:
            t = s.sim_time_ns
            tr = truth.get(t)
            if tr is not None:
                st = tr[2]
                for reading, fuse in (
                    (mag.sample(st), nav.fuse_heading),  # type: ignore[arg-type]
                    (baro.sample(st), nav.fuse_baro),  # type: ignore[arg-type]
                    (tas.sample(st), nav.fuse_airspeed),  # type: ignore[arg-type]
                ):
                    if reading is not None:
                        fuse(reading, t)  # type: ignore[operator]
            fix = fixes.get(t)
            if fix is not None and (deny_from_ns is None or t < deny_from_ns):
                nav.fuse_gnss(fix, t)
            nav.predict(s)
            if tr is not None and c0 + 10 * 10**9 <= t <= c1:
                e = nav.estimate()
                out.append((t, e.pos_ned_m[0] - tr[0], e.pos_ned_m[1] - tr[1]))
        return out

    import math

    errs = [math.hypot(dn, de) for _, dn, de in run(None)]
    mid = (c0 + c1) // 2
    denied = run(mid)
    after = [(t - mid) / 1e9 for t, _, _ in denied]
    dr = [math.hypot(dn, de) for t, dn, de in denied if t >= mid]
    at = {round(dt): math.hypot(dn, de) for dt, (_, dn, de) in zip(after, denied, strict=True)}
    marks = ", ".join(f"{k} s {at[k]:.1f} m" for k in (30, 60, 120) if k in at)
    print(
        f"{folder.name}: IMU from take-off, GNSS of the capture window ({(c1 - c0) / 1e9:.0f} s):"
        f" p95 {percentile(errs, 95):.2f} m, max {max(errs):.2f} m; GNSS cut at mid-capture:"
        f" {marks}, end ({max(after):.0f} s) {dr[-1]:.1f} m"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", default="UC-200,FL-200,FR-200")
    parser.add_argument("--seconds", type=float, default=240.0)
    parser.add_argument("--cost-only", action="store_true")
    parser.add_argument("--archive", type=Path, action="append", default=[])
    args = parser.parse_args()
    if args.archive:
        for folder in args.archive:
            archive(folder)
        return
    names = [s.strip() for s in args.scenarios.split(",") if s.strip()]
    cost(names[0], min(args.seconds, 120.0))
    if not args.cost_only:
        for name in names:
            accuracy(name, args.seconds)


if __name__ == "__main__":
    main()
