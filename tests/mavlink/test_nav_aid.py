"""The onboard filter over MAVLink (``serve --nav-aid mavlink``): aid messages decoded, a
pymavlink companion (ids 1/197) feeding VISION_POSITION_ESTIMATE at 20 Hz during GNSS denial
while MAVSDK flies a plan, bad aid input, and the estimate's telemetry.

The vehicle runs in this process (as :mod:`inproc`), so the companion can read the truth it
sends as its "vision" position, and the test can read the filter's counters at the end.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from gcs import SAFETY_S, Gcs, free_udp_port
from inproc import Vehicle, running_vehicle
from pymavlink import mavutil
from short_plans import write_short_plan

from air_sitl.mavlink.codec import mav
from air_sitl.mavlink.nav_aid import EV_AID, GLOBAL_AID, NavLink
from air_sitl.mission.plan_file import load_mission
from air_sitl.nav.types import AidFrame
from air_sitl.state import GeoPoint, VehicleState

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
NS = 1_000_000_000
NAN = math.nan


# ------------------------------------------------------------------ decoding (no flight)


class _Params:
    def __init__(self, **values: float) -> None:
        self.values = {"EKF2_EV_CTRL": 1.0, "EKF2_EV_NOISE_MD": 0.0, "EKF2_EVP_NOISE": 5.0}
        self.values.update(values)

    def get(self, name: str) -> float:
        return self.values[name]


def _decoder(**params: float) -> NavLink:
    link = NavLink.__new__(NavLink)
    link.params = _Params(**params)  # type: ignore[assignment]
    link.ignored = 0
    return link


def _cov21(xx: float, yy: float, xy: float = 0.0) -> list[float]:
    c = [0.0] * 21
    c[0], c[1], c[6], c[11] = xx, xy, yy, 9.0
    return c


def test_vision_position_estimate_is_a_ned_position_at_its_own_time() -> None:
    msg = mav.MAVLink_vision_position_estimate_message(
        12_345_678, 10.0, -20.0, -200.0, 0, 0, 0, _cov21(4.0, 9.0, 1.0)
    )
    m = _decoder().decode(msg)
    assert m is not None and m.name == EV_AID and m.frame == AidFrame.NED.value
    assert m.sim_time_ns == 12_345_678_000 and m.position == (10.0, -20.0, -200.0)
    assert m.cov_m2 is not None and (m.cov_m2[0], m.cov_m2[1], m.cov_m2[4]) == (4.0, 1.0, 9.0)
    # Unknown covariance (NaN first) or EKF2_EV_NOISE_MD 1: EKF2_EVP_NOISE.
    msg.covariance = [NAN] * 21
    m = _decoder(EKF2_EVP_NOISE=3.0).decode(msg)
    assert m is not None and m.cov_m2 is None and m.sigma_m == 3.0
    msg.covariance = _cov21(4.0, 9.0)
    m = _decoder(EKF2_EV_NOISE_MD=1, EKF2_EVP_NOISE=2.0).decode(msg)
    assert m is not None and m.cov_m2 is None and m.sigma_m == 2.0
    # EKF2_EV_CTRL bit 0 off: not fused at all.
    link = _decoder(EKF2_EV_CTRL=0)
    assert link.decode(msg) is None and link.ignored == 1


def _odometry(frame_id: int) -> Any:
    return mav.MAVLink_odometry_message(
        5_000_000, frame_id, mav.MAV_FRAME_BODY_FRD, 1.0, 2.0, -3.0, [1, 0, 0, 0],
        0, 0, 0, 0, 0, 0, _cov21(1.0, 1.0), [NAN] * 21,
    )  # fmt: skip


def test_odometry_frames() -> None:
    ned = _decoder().decode(_odometry(mav.MAV_FRAME_LOCAL_NED))
    enu = _decoder().decode(_odometry(mav.MAV_FRAME_LOCAL_ENU))
    frd = _decoder().decode(_odometry(mav.MAV_FRAME_LOCAL_FRD))
    assert ned is not None and ned.frame == "ned" and ned.sim_time_ns == 5_000_000_000
    assert enu is not None and enu.frame == "enu"
    # Not aligned with north: an unknown frame to the filter (rejected and counted there).
    assert frd is not None and frd.frame not in {f.value for f in AidFrame}


def test_gps_input_and_global_position_sensor_are_lat_lon() -> None:
    gi = mav.MAVLink_gps_input_message(
        7_000_000, 0, 0, 0, 0, 3, 546872000, 252797000, 320.0, 1.0, 1.0, 0, 0, 0, 0, 2.5, 3.0, 12
    )
    m = _decoder().decode(gi)
    assert m is not None and m.name == GLOBAL_AID and m.frame == "wgs84"
    assert m.position == pytest.approx((54.6872, 25.2797, 320.0)) and m.sigma_m == 2.5
    gi.fix_type = 1
    m = _decoder().decode(gi)
    assert m is not None and m.position is None  # no fix: an empty answer
    gps = mav.MAVLink_global_position_sensor_message(
        1, 1, 0, 8_000_000, 0, 0, 0, 546872000, 252797000, 0.0, 320.0, 4.0, 6.0
    )
    m = _decoder().decode(gps)
    assert m is not None and m.sigma_m == 4.0 and m.sim_time_ns == 8_000_000_000


# ------------------------------------------------------------------ a served flight


@contextlib.contextmanager
def served_with_aid(
    plan: Path, *, deny_after_s: float, speed: float
) -> Iterator[tuple[Vehicle, int]]:
    """``serve --plan PLAN --nav-aid mavlink --gps-denied-after S`` in this process; the
    vehicle and the port of the ground station it sends to."""
    port = free_udp_port()
    with running_vehicle(
        [f"udpout:127.0.0.1:{port}"],
        HOME,
        speed=speed,
        mission=load_mission(plan),
        aided_denied_after_s=deny_after_s,
    ) as vehicle:
        yield vehicle, port


class Companion:
    """A pymavlink companion computer (1/197) sending the truth as VISION_POSITION_ESTIMATE at
    ``rate_hz`` of simulated time, from ``start_s``. It follows simulated time exactly: it
    sends from the truth sink's listener, on the simulation thread, one message a slot, so a
    busy machine changes nothing about what it sends or when (in simulated time)."""

    def __init__(self, served: Vehicle, *, start_s: float, rate_hz: float = 20.0) -> None:
        self.served = served
        self.start_ns = round(start_s * NS)
        self.period_ns = round(NS / rate_hz)
        self.conn: Any = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{served.endpoint.links[0].local_address[1]}",
            source_system=1, source_component=197, dialect="common",
        )  # fmt: skip
        # MAVLink 2 (ODOMETRY's id needs it), our sender ids.
        self.mav = mav.MAVLink(self.conn, srcSystem=1, srcComponent=197)
        self.sent = 0
        # Messages to send instead of the good ones, one per slot (None: the good one).
        self.extra: list[Any] = []
        self._last_slot = -1

    def __enter__(self) -> Companion:
        self.served.truth.listeners.append(self._on_state)
        return self

    def __exit__(self, *_exc: object) -> None:
        self.served.truth.listeners.remove(self._on_state)
        self.conn.close()

    def _on_state(self, s: VehicleState) -> None:
        t = s.sim_time_ns
        slot = t // self.period_ns
        if t < self.start_ns or slot == self._last_slot:
            return
        self._last_slot = slot
        bad = self.extra.pop(0) if self.extra else None
        if bad is not None:
            bad(self.mav, t)  # instead of this slot's good position
            return
        n, e, d = s.pos_ned_m
        self.mav.vision_position_estimate_send(t // 1000, n, e, d, 0.0, 0.0, 0.0, _cov21(9.0, 9.0))
        self.sent += 1


def test_a_companion_aids_a_denied_flight_that_mavsdk_sees_finish(tmp_path: Path) -> None:
    from mavsdk.asyncio.plugins.action import ActionAsync
    from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
    from mavsdk_wait import ground_station, until_answered

    # The denial (from 40 s) lasts over 80 s of the flight: more than the 30 s asserted.
    plan = write_short_plan(tmp_path / "AID.plan", HOME, leg_m=200.0)

    async def fly(port: int) -> list[tuple[int, int]]:
        async with ground_station(port, timeout_s=SAFETY_S) as system:
            mission = MissionRawAsync(system)
            action = ActionAsync(system)
            imported = await mission.import_qgroundcontrol_mission(str(plan))
            items = imported.mission_items
            await until_answered(lambda: mission.upload_mission(items), timeout_s=SAFETY_S)
            await until_answered(action.arm, timeout_s=SAFETY_S)
            await until_answered(mission.start_mission, timeout_s=SAFETY_S)
            seen: list[tuple[int, int]] = []
            async for progress in mission.subscribe_mission_progress():
                seen.append((progress.current, progress.total))
                if progress.total > 0 and progress.current == progress.total:
                    break
            assert await mission.is_mission_finished()
            return seen

    with (
        served_with_aid(plan, deny_after_s=40.0, speed=8.0) as (served, port),
        Companion(served, start_s=35.0) as companion,
    ):
        companion.extra = bad_inputs()
        seen = asyncio.run(asyncio.wait_for(fly(port), timeout=600))
        # A ground station connecting now sees the estimate's telemetry.
        gcs = Gcs(f"udpout:127.0.0.1:{served.endpoint.links[0].local_address[1]}")
        try:
            gcs.connect()
            raw = gcs.recv(["GPS_RAW_INT"])
            status = gcs.recv(["ESTIMATOR_STATUS"])
            position = gcs.recv(["GLOBAL_POSITION_INT"])
        finally:
            gcs.close()
        nav = served.flight.nav
        assert nav is not None
        summary = nav.summary()["nav"]
        estimate = nav.estimate
    assert seen[-1][0] == seen[-1][1]
    assert raw.fix_type == 0  # denied: no fix, whatever the last one was
    assert status.flags & mav.ESTIMATOR_POS_HORIZ_ABS  # the aid is an absolute position
    assert estimate is not None
    assert abs(position.lat * 1e-7 - estimate.lat_deg) < 1e-3  # the estimate, not the truth
    aid = summary["aid"]
    assert aid["name"] == "mavlink" and aid["fused"] > 0.8 * companion.sent > 100, aid
    reasons = aid["rejected_by_reason"]
    for reason in ("invalid", "future", "stale", "frame", "gate"):
        assert reasons.get(reason, 0) >= 1, reasons
    assert reasons.get("rate", 0) + reasons.get("order", 0) >= 50, reasons
    assert summary["gnss_denied_s"] > 30.0
    assert summary["horizontal_error_denied_m"]["p95"] < 8.0, summary
    assert any("GNSS lost" in e for e in summary["events"])


def bad_inputs() -> list[Any]:
    """Bad aid messages, each sent once beside a good one: NaN, a 200 m jump (for 1 s),
    a time from the future and from the far past, an unknown frame, a flood at 1 kHz."""

    def vpe(dn: float = 0.0, dt_us: int = 0, nan: bool = False) -> Any:
        def send(m: Any, t_ns: int) -> None:
            x = NAN if nan else 0.0
            m.vision_position_estimate_send(t_ns // 1000 + dt_us, x, dn, -200.0, 0, 0, 0,
                                            _cov21(9.0, 9.0))  # fmt: skip

        return send

    def odometry_frd(m: Any, t_ns: int) -> None:
        m.odometry_send(t_ns // 1000, mav.MAV_FRAME_LOCAL_FRD, mav.MAV_FRAME_BODY_FRD, 0, 0, 0,
                        [1, 0, 0, 0], 0, 0, 0, 0, 0, 0, _cov21(1, 1), [NAN] * 21)  # fmt: skip

    def flood(m: Any, t_ns: int) -> None:
        for k in range(100):
            m.vision_position_estimate_send(t_ns // 1000 - 1000 * k, 0, 0, -200, 0, 0, 0,
                                            _cov21(9.0, 9.0))  # fmt: skip

    wait = [None] * 400  # 20 s at 20 Hz: into the denial, the aid established
    return [
        *wait,
        vpe(nan=True),
        vpe(dt_us=30_000_000),  # 30 s in the future
        vpe(dt_us=-30_000_000),  # 30 s in the past
        odometry_frd,
        flood,
        *[vpe(dn=200.0)] * 20,  # 1 s of positions far off the track (300 m north of home)
    ]
