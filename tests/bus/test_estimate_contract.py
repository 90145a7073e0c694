"""Garbage on ``estimate/<name>`` never reaches ``estimates/<name>.csv``: every estimate is
checked against the contract and the flight, one row per frame (the first), rejections
counted by reason, decode errors (OverflowError, RecursionError, bad JSON) counted too, and
the number of estimator names capped. Over real zenoh sessions and a real ``fly``."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import threading
from pathlib import Path

import pytest
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.bus import codec
from air_sitl.bus import estimate_contract as contract
from air_sitl.bus.estimates import ESTIMATE_COLUMNS, EstimateLog
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import FrameLedger
from air_sitl.bus.session import BusConfig, Message, open_bus
from air_sitl.clock import CAMERA_PERIOD_NS

from .helpers import HOME, cli, free_endpoint, pair, wait_until

KEYS = KeySpace("uav0")
DEEP = b"[" * 200_000 + b"]" * 200_000


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b'{"frame": 1, "enu_m": [1e308, 1e308, 1e308]}', contract.IMPLAUSIBLE),
        (b'{"frame": 1, "enu_m": [0, 0, 2e6]}', contract.IMPLAUSIBLE),
        (
            b'{"frame": 1, "lat_deg": 54.7, "lon_deg": 25.3, "alt_amsl_m": Infinity}',
            contract.NON_FINITE,
        ),
        (
            b'{"frame": 1, "lat_deg": 54.7, "lon_deg": 25.3, "alt_amsl_m": 1e7}',
            contract.IMPLAUSIBLE,
        ),
        (
            b'{"frame": 1, "enu_m": [1, 2, 3], "q_body_to_ned_wxyz": [5, 0, 0, 0]}',
            contract.IMPLAUSIBLE,
        ),
        (
            b'{"frame": 1, "enu_m": [1, 2, 3], "cov_enu_m2": [-1, 0, 0, 0, 1, 0, 0, 0, 1]}',
            contract.IMPLAUSIBLE,
        ),
        (b'{"sim_time_ns": -5, "enu_m": [1, 2, 3]}', contract.OUTSIDE_FLIGHT),
        (b'{"frame": 1e400, "enu_m": [1, 2, 3]}', contract.NON_FINITE),
        (b'{"frame": 2.5, "enu_m": [1, 2, 3]}', contract.MALFORMED),
        (b'{"frame": "7", "enu_m": [1, 2, 3]}', contract.MALFORMED),
        (b'{"frame": 1, "enu_m": [1, "x", 3]}', contract.MALFORMED),
        (DEEP, contract.MALFORMED),
        (b'{"frame": ' + b"9" * 5000 + b"}", contract.MALFORMED),
        (b"\xff\xfe", contract.MALFORMED),
        (b'{"enu_m": [1, 2, 3]}', contract.NO_FRAME_OR_TIME),
    ],
)
def test_each_breach_of_the_contract_has_its_reason(payload: bytes, reason: str) -> None:
    with pytest.raises(contract.EstimateRejectedError) as info:
        codec.decode_estimate(payload, "air/uav0/estimate/x")
    assert info.value.reason == reason
    assert "\n" not in str(info.value) and "air/uav0/estimate/x" in str(info.value)
    assert len(str(info.value)) < 300


def test_good_estimates_still_pass() -> None:
    est = codec.decode_estimate(
        b'{"frame": 3.0, "enu_m": [1, null, 3], "q_body_to_ned_wxyz": [1, 0, 0, 0]}', "k"
    )
    assert est.frame == 3 and est.enu_m is not None and math.isnan(est.enu_m[1])


def test_the_log_keeps_one_good_row_per_frame_and_counts_the_rest(tmp_path: Path) -> None:
    sim, est = pair(free_endpoint())
    with sim, est:
        ledger = FrameLedger()
        log = EstimateLog(sim, KEYS, ledger, out_dir=tmp_path, home=HOME, max_names=4)
        for k in range(3):
            ledger.record(k, k * CAMERA_PERIOD_NS, k)
        ledger.now_ns = 2 * CAMERA_PERIOD_NS
        out = est.publisher(KEYS.estimate("dr"), encoding=codec.JSON_ENCODING)
        assert wait_until(lambda: out.matched)
        garbage = [
            b'{"frame": 0, "enu_m": [1e308, 1e308, 1e308]}',
            b'{"frame": 0, "lat_deg": 54.7, "lon_deg": 25.3, "alt_amsl_m": Infinity}',
            b'{"sim_time_ns": -5, "enu_m": [1, 2, 3]}',
            b'{"frame": 1e400}',
            DEEP,
            b'{"frame": 99, "enu_m": [1, 2, 3]}',  # never taken
            b'{"sim_time_ns": 999000000000, "enu_m": [1, 2, 3]}',  # after the flight so far
        ]
        for payload in garbage:
            out.put(payload)
        out.put(codec.encode_estimate(frame=0, enu_m=(1.0, 2.0, 200.0)))
        out.put(codec.encode_estimate(frame=0, enu_m=(9.0, 9.0, 209.0)))  # duplicate
        out.put(codec.encode_estimate(frame=1, enu_m=(2.0, 2.0, 200.0)))
        spam = [est.publisher(KEYS.estimate(f"s{i}"), encoding=codec.JSON_ENCODING)
                for i in range(10)]  # fmt: skip
        for p in spam:
            assert wait_until(lambda p=p: p.matched)  # type: ignore[misc]
            p.put(codec.encode_estimate(frame=2, enu_m=(0.0, 0.0, 200.0)))
        assert wait_until(lambda: log.rejected_total() == len(garbage) + 1 + 7)
        log.close()
    assert log.rejected == {
        contract.IMPLAUSIBLE: 1,
        contract.NON_FINITE: 2,
        contract.OUTSIDE_FLIGHT: 3,
        contract.MALFORMED: 1,
        contract.DUPLICATE: 1,
        contract.TOO_MANY_NAMES: 7,  # 4 names: dr and s0..s2
    }
    assert sim.callback_errors == []
    with (tmp_path / "estimates" / "dr.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(ESTIMATE_COLUMNS)
    assert [(r["frame"], r["east_m"]) for r in rows] == [("0", "1.0000"), ("1", "2.0000")]
    files = sorted(p.name for p in (tmp_path / "estimates").iterdir())
    assert files == ["dr.csv", "s0.csv", "s1.csv", "s2.csv"]


def test_a_flight_reports_rejections_and_unanswered_frames(tmp_path: Path) -> None:
    """fly --zenoh beside an estimator that answers every other frame twice and sends
    garbage: the CSV holds one row per answered frame, summary.json and stderr count the
    rest by reason, and the unanswered frames."""
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=30.0, name="UB")
    endpoint = free_endpoint()
    session = open_bus(BusConfig(listen=(endpoint,), connect=()))
    answered: list[int] = []
    lock = threading.Lock()
    with session:
        est_pub = session.publisher(KEYS.estimate("odd"), encoding=codec.JSON_ENCODING, block=True)

        def on_frame(message: Message) -> None:
            meta = json.loads(message.attachment or b"{}")
            frame = int(meta["frame"])
            if frame % 2:
                return
            good = codec.encode_estimate(frame=frame, enu_m=(float(frame), 0.0, 200.0))
            est_pub.put(good)
            est_pub.put(good)  # the same answer again (a re-offered frame): no news
            est_pub.put(codec.encode_estimate(frame=frame, enu_m=(9.0, 9.0, 209.0)))  # another
            est_pub.put(b'{"frame": %d, "enu_m": [1e308, 0, 0]}' % frame)
            with lock:
                answered.append(frame)

        session.subscribe(KEYS.image, on_frame)
        out = tmp_path / "out"
        flown = subprocess.run(
            cli("fly", str(plan), "--air-start", "--quiet", "--out", str(out), "--zenoh",
                "--zenoh-connect", endpoint, "--svo-columns", "odd", *SMALL_CAMERA),
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
    assert flown.returncode == 0, flown.stderr
    summary = json.loads((out / "summary.json").read_text())
    n = summary["frames_published"]
    assert n == summary["capture_frames"] > 50
    got = len(answered)  # frames go out drop-on-congestion: the estimator may miss a few
    assert 0 < got <= (n + 1) // 2
    assert summary["estimates"] == {"odd": got}
    assert summary["estimates_rejected"] == {"duplicate_frame": got, "implausible": got}
    assert summary["frames_without_estimate"] == {"odd": n - got}
    assert f"{2 * got} estimate(s) rejected (duplicate_frame {got}, implausible {got})" in (
        flown.stderr
    )
    assert f"{n - got} of {n} frames got no estimate from 'odd'" in flown.stderr
    with (out / "estimates" / "odd.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [int(r["frame"]) for r in rows] == sorted(answered)
    assert all(math.isfinite(float(r["east_m"])) for r in rows)


def test_a_flight_says_when_the_awaited_estimator_never_spoke(tmp_path: Path) -> None:
    """At real-time pace the flight goes on over 7 s after its first frame (the capture leg,
    then 60 m to the last waypoint): the warning, 5 s after that frame, comes during the
    flight (before the end's), and again at the end."""
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=60.0, name="UB")
    out = tmp_path / "out"
    flown = subprocess.run(
        cli("fly", str(plan), "--air-start", "--quiet", "--out", str(out), "--speed", "1",
            "--zenoh-listen", free_endpoint(), "--svo-columns", "nobody", *SMALL_CAMERA),
        capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert flown.returncode == 0, flown.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["estimates_missing"] == ["nobody"]
    lines = flown.stderr.splitlines()
    during = "no estimate from 'nobody' on air/uav0/estimate/nobody 5 s after the first frame"
    at_end = "no estimate from 'nobody' on air/uav0/estimate/nobody in the whole flight"
    assert [i for i, line in enumerate(lines) if during in line] == [0], lines
    assert [i for i, line in enumerate(lines) if at_end in line] == [1], lines


def test_max_estimate_names_is_an_option(tmp_path: Path) -> None:
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=30.0, name="UB")
    bad = subprocess.run(
        cli("fly", str(plan), "--zenoh", "--max-estimate-names", "0"),
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert bad.returncode == 2
    assert bad.stderr.strip().splitlines()[-1].startswith("air-sitl: error: ")
    assert "--max-estimate-names" in bad.stderr
