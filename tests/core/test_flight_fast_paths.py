"""The flight step's fast paths write what the plain code wrote (issue 34).

The trajectory's rows and the estimate's columns are formatted with ``%`` in one call instead
of an f-string per field, and the writers make them compiled (text_kernel): the same text for
every float (rounding edges and exact ties, NaN, infinities, signed zeros, huge and tiny
values). Two air-start cruises of FR-300 (legs, turns, the capture
window, settled tracking, the battery) give the bytes of 0c6e142, the code before these paths:
every sample at full precision, the summary and the trajectory file.
"""

from __future__ import annotations

import hashlib
import json
import math
import random
from pathlib import Path

import pytest

from air_sitl.builder import build_flight, load_setup
from air_sitl.flightlog import NavTrajectoryWriter, TrajectoryWriter, _row
from air_sitl.nav.columns import nav_fields
from air_sitl.options import FlightOptions
from air_sitl.sinks import FlightResult
from air_sitl.state import (
    AutopilotStatus,
    FlightMode,
    NavEstimate,
    NavFlags,
    SimSample,
    mission_sample,
    vehicle_state,
)

REPO = Path(__file__).resolve().parents[2]

EDGES = [
    math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, -5e-324, 1e300, -1e300, 0.5, 2.5,
    0.00005, 0.000049999999, 1.23456785, 52.1234567895, -0.00000000049, 123456789.123456789,
]  # fmt: skip


def _values(rng: random.Random, n: int, edges: float = 0.3) -> list[float]:
    """Edge values first (a share ``edges``), then random ones on several scales and exact
    ties of the rounding (odd multiples of half a unit of the last decimal kept)."""
    out = [rng.choice(EDGES) if rng.random() < edges else 0.0 for _ in range(n)]
    for i in range(n):
        if out[i] == 0.0 and rng.random() < 0.9:
            if rng.random() < 0.3:
                k = rng.choice((4, 6, 8, 9))
                out[i] = (2 * rng.randint(-(10**7), 10**7) + 1) / (2 * 10**k)
            else:
                out[i] = rng.uniform(-1.0, 1.0) * 10.0 ** rng.randint(-9, 8)
    return out


# The format spec of each float column, as the f-strings of 0c6e142 had them.
ROW_SPECS = (".9f", ".9f", ".4f") + (".4f",) * 3 + (".8f",) * 4 + (".4f",) * 3 + (".6f",) * 3
NAV_SPECS = (".4f", ".4f", ".4f", ".9f", ".9f", ".4f", ".4f")


def _formatted(values: tuple[float, ...], specs: tuple[str, ...]) -> list[str]:
    assert len(values) == len(specs)
    return [format(v, spec) for v, spec in zip(values, specs, strict=True)]


def _plain_row(sample: SimSample) -> str:
    """The row as 0c6e142 wrote it: each value through its own format spec."""
    s = sample.state
    a = sample.autopilot
    floats = (s.lat_deg, s.lon_deg, s.alt_amsl_m, *s.pos_ned_m, *s.q_body_to_ned_wxyz,
              *s.vel_ned_m_s, *s.rate_frd_rad_s)  # fmt: skip
    fields = [str(s.sim_time_ns), *_formatted(floats, ROW_SPECS)]
    fields += [format(s.airspeed_m_s, ".4f"), a.mode.value, str(a.current_seq)]
    return ",".join([*fields, str(int(a.capturing))]) + "\n"


def _plain_nav(est: NavEstimate) -> str:
    n, e, d = est.pos_ned_m
    values = (e, n, -d, est.lat_deg, est.lon_deg, est.alt_amsl_m, est.std_h_m)
    return ",".join(_formatted(values, NAV_SPECS))


def test_rows_are_the_text_of_the_f_strings() -> None:
    rng = random.Random(34)
    modes = list(FlightMode)
    for k in range(3000):
        v = _values(rng, 24)
        state = vehicle_state(
            rng.randint(0, 10**13), v[0], v[1], v[2], v[3], (v[4], v[5], v[6]),
            (v[7], v[8], v[9], v[10]), 0.0, 0.0, 0.0, (v[11], v[12], v[13]),
            (v[14], v[15], v[16]), (0.0, 0.0, -9.8), v[17], False,
        )  # fmt: skip
        sample = mission_sample(state)
        status = AutopilotStatus(
            mode=modes[k % len(modes)], armed=True, current_seq=rng.randint(-1, 40),
            capturing=k % 3 == 0, mission_completed=False,
        )  # fmt: skip
        sample = SimSample(state=state, autopilot=status, imu=sample.imu, gps=None)
        assert _row(sample) == _plain_row(sample)
        flags = NavFlags(**{name: True for name in NavFlags.__dataclass_fields__})
        est = NavEstimate(
            sim_time_ns=0, pos_ned_m=(v[18], v[19], v[20]), vel_ned_m_s=(0.0, 0.0, 0.0),
            q_body_to_ned_wxyz=(1.0, 0.0, 0.0, 0.0), lat_deg=v[21], lon_deg=v[22],
            alt_amsl_m=v[23], std_h_m=v[k % 24], std_v_m=1.0, wind_ned_m_s=(0.0, 0.0),
            gyro_bias_rad_s=(0.0, 0.0, 0.0), accel_bias_m_s2=(0.0, 0.0, 0.0), flags=flags,
        )  # fmt: skip
        assert nav_fields(est) == _plain_nav(est)


@pytest.mark.parametrize("nav", [True, False])
def test_the_writers_files_are_the_text_of_the_f_strings(tmp_path: Path, nav: bool) -> None:
    """Rows made compiled, and (a value not finite or huge) by Python, in the file in
    order: the text of the plain rows."""
    rng = random.Random(35)
    modes = list(FlightMode)
    path = tmp_path / "trajectory.csv"
    writer = (NavTrajectoryWriter if nav else TrajectoryWriter)(path)
    expected = []
    for k in range(4000):
        v = _values(rng, 25, edges=0.01)
        state = vehicle_state(
            (k + rng.randint(0, 3)) * 20_000_000 + k * 80_000_000, v[0], v[1], v[2], v[3],
            (v[4], v[5], v[6]), (v[7], v[8], v[9], v[10]), 0.0, 0.0, 0.0,
            (v[11], v[12], v[13]), (v[14], v[15], v[16]), (0.0, 0.0, -9.8), v[17], False,
        )  # fmt: skip
        status = AutopilotStatus(
            mode=modes[k % len(modes)], armed=True, current_seq=rng.randint(-1, 40),
            capturing=k % 3 == 0, mission_completed=False,
        )  # fmt: skip
        flags = NavFlags(**{name: True for name in NavFlags.__dataclass_fields__})
        est = None
        if k % 5:
            est = NavEstimate(
                sim_time_ns=0, pos_ned_m=(v[18], v[19], v[20]), vel_ned_m_s=(0.0, 0.0, 0.0),
                q_body_to_ned_wxyz=(1.0, 0.0, 0.0, 0.0), lat_deg=v[21], lon_deg=v[22],
                alt_amsl_m=v[23], std_h_m=v[24], std_v_m=1.0, wind_ned_m_s=(0.0, 0.0),
                gyro_bias_rad_s=(0.0, 0.0, 0.0), accel_bias_m_s2=(0.0, 0.0, 0.0), flags=flags,
            )  # fmt: skip
        imu = mission_sample(state).imu
        sample = SimSample(state=state, autopilot=status, imu=imu, gps=None, nav=est)
        writer.on_sample(sample)
        row = _plain_row(sample)
        if nav:
            row = row[:-1] + "," + (",,,,,," if est is None else _plain_nav(est)) + "\n"
        expected.append(row)
    writer.close(FlightResult(mission_completed=False, sim_time_ns=0, wall_time_s=1.0))
    header = ",".join(writer.columns()) + "\n"
    text = path.read_text()
    assert text.count("nan") > 10 and text.count("inf") > 10  # rows made by Python among them
    assert text == header + "".join(expected)


@pytest.mark.integration
@pytest.mark.parametrize(
    ("nav", "digest"),
    [
        ("ekf", "8caad56065a0f1d0966371ce45b190ee5e9233b84d1792e64246b1800f088ae8"),
        ("truth", "865c404ab885f345ce6bffc9a45c57c6bd3913c36e3ca9c8c39ff7138b3381dc"),
    ],
)
def test_a_cruise_is_that_of_0c6e142(tmp_path: Path, nav: str, digest: str) -> None:
    path = tmp_path / "trajectory.csv"
    writer = (NavTrajectoryWriter if nav == "ekf" else TrajectoryWriter)(path)
    options = FlightOptions(nav=nav, air_start=True)
    flight = build_flight(load_setup(REPO / "missions" / "FR-300.plan", options), sinks=[writer])
    h = hashlib.sha256()
    for _ in range(120 * 200):  # 120 simulated seconds: four waypoints, 4,300 capture frames
        h.update(repr(flight.step()).encode())
    writer.close(FlightResult(mission_completed=False, sim_time_ns=0, wall_time_s=1.0))
    summary = flight.stats.summary(1.0)
    assert summary["waypoints_reached"] == 4
    assert summary["max_cross_track_m"] is not None
    h.update(json.dumps(summary, sort_keys=True).encode())
    h.update(path.read_bytes())
    assert h.hexdigest() == digest
