"""Stream rates: per link (SET_MESSAGE_INTERVAL, REQUEST_DATA_STREAM), delivered in full.

Rates are counted per simulated second from the ``time_boot_ms`` of the messages received, so a
busy machine changes how long a test takes, never its outcome.
"""

from __future__ import annotations

from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor

import pytest
from gcs import Gcs, serve
from inproc import running_vehicle
from pymavlink import mavutil

from air_sitl.mavlink.telemetry import DEFAULT_RATES_HZ
from air_sitl.mavlink.vehicle import EndpointOptions
from air_sitl.state import GeoPoint

M = mavutil.mavlink
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
ATTITUDE = M.MAVLINK_MSG_ID_ATTITUDE
pytestmark = pytest.mark.integration


def per_sim_second(gcs: Gcs, kind: str, sim_s: float) -> float:
    """Messages of ``kind`` per simulated second over ``sim_s`` seconds (by time_boot_ms)."""
    gcs.drain()
    gcs.collect([kind], 0.5)  # let a rate change settle
    start_ms = gcs.sim_ms
    msgs = gcs.collect([kind], sim_s)
    assert len(msgs) >= 2, f"no {kind} stream"
    if hasattr(msgs[0], "time_boot_ms"):
        # Messages built from the onboard estimate carry its time, a step or two behind.
        return (len(msgs) - 1) / ((msgs[-1].time_boot_ms - msgs[0].time_boot_ms) / 1000)
    return len(msgs) / ((gcs.sim_ms - start_ms) / 1000)  # VFR_HUD: counted against the clock


def only(gcs: Gcs, keep: int) -> None:
    """Turn every default stream but ``keep`` off on the GCS's link."""
    for msg_id in DEFAULT_RATES_HZ:
        if msg_id != keep:
            assert gcs.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, -1) == (
                M.MAV_RESULT_ACCEPTED
            )


def request_data_stream(gcs: Gcs, stream: int, rate_hz: int, start: int) -> None:
    """REQUEST_DATA_STREAM (no answer in MAVLink), then an acknowledged command on the same
    link: the vehicle handles a link's messages in order, so once that ACK is here the stream
    change has been made (a busy machine may take longer than a simulated second for it)."""
    gcs.conn.mav.request_data_stream_send(1, 1, stream, rate_hz, start)
    version = M.MAVLINK_MSG_ID_AUTOPILOT_VERSION
    assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, version) == M.MAV_RESULT_ACCEPTED


@pytest.fixture
def two_links() -> Iterator[tuple[Gcs, Gcs]]:
    """A vehicle at 10x real time, without wall-clock cap, with one GCS on each of two links."""
    options = EndpointOptions(wall_cap_hz=None)
    links = ["udpin:127.0.0.1:0", "udpin:127.0.0.1:0"]
    with running_vehicle(links, HOME, speed=10.0, options=options) as vehicle:
        a, b = (Gcs(f"udpout:127.0.0.1:{link.local_address[1]}") for link in vehicle.endpoint.links)
        # Side by side: each waits for a HEARTBEAT, which the vehicle sends once a wall second.
        with ThreadPoolExecutor(2) as pool:
            list(pool.map(Gcs.connect, (a, b)))
        yield a, b
        a.close()
        b.close()


@pytest.mark.parametrize("rate_hz", [10.0, 50.0])
def test_set_message_interval_is_per_link_and_delivered_in_full(
    two_links: tuple[Gcs, Gcs], rate_hz: float
) -> None:
    a, b = two_links
    only(a, ATTITUDE)
    only(b, ATTITUDE)
    interval_us = 1e6 / rate_hz
    assert a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, interval_us) == M.MAV_RESULT_ACCEPTED
    assert per_sim_second(a, "ATTITUDE", 10.0) == pytest.approx(rate_hz, rel=0.05)
    # The other link keeps its own (default) rate.
    assert per_sim_second(b, "ATTITUDE", 10.0) == pytest.approx(20.0, rel=0.05)
    # -1 stops the stream on link a only (GLOBAL_POSITION_INT keeps the clock there).
    position = M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT
    assert a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, position, 0) == M.MAV_RESULT_ACCEPTED
    assert a.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, -1) == M.MAV_RESULT_ACCEPTED
    a.drain()
    a.collect(["ATTITUDE"], 0.5)  # what was sent before the stop
    start = a.sim_ms
    later = a.collect(["ATTITUDE"], 3.0)
    assert [m for m in later if m.time_boot_ms > start] == []
    assert per_sim_second(b, "ATTITUDE", 3.0) == pytest.approx(20.0, rel=0.05)


def test_request_data_stream_sets_groups_per_link_as_ardupilot(two_links: tuple[Gcs, Gcs]) -> None:
    a, b = two_links
    only(b, ATTITUDE)
    # MAVProxy's way: every group at its stream rate, then one group changed.
    request_data_stream(a, M.MAV_DATA_STREAM_ALL, 4, 1)
    assert per_sim_second(a, "GLOBAL_POSITION_INT", 10.0) == pytest.approx(4.0, rel=0.05)
    request_data_stream(a, M.MAV_DATA_STREAM_EXTRA1, 25, 1)
    assert per_sim_second(a, "ATTITUDE", 10.0) == pytest.approx(25.0, rel=0.05)
    assert per_sim_second(a, "VFR_HUD", 10.0) == pytest.approx(4.0, rel=0.05)
    assert per_sim_second(b, "ATTITUDE", 10.0) == pytest.approx(20.0, rel=0.05)
    # Stopping a group (start_stop 0) stops its messages on that link only.
    request_data_stream(a, M.MAV_DATA_STREAM_POSITION, 0, 0)
    a.drain()
    a.collect(["GLOBAL_POSITION_INT"], 1.0)  # what was queued before the stop
    start = a.sim_ms
    later = a.collect(["GLOBAL_POSITION_INT", "ATTITUDE"], 3.0)
    assert not [
        m for m in later if m.get_type() == "GLOBAL_POSITION_INT" and m.time_boot_ms > start
    ]
    assert [m for m in later if m.get_type() == "ATTITUDE"]


@pytest.mark.parametrize("speed", ["1", "3"])
def test_50_hz_is_delivered_by_serve_within_5_percent(speed: str) -> None:
    """At --speed 1 (wall = simulated second) and faster, under the wall-clock cap."""
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", speed) as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        assert (
            gcs.command(M.MAV_CMD_SET_MESSAGE_INTERVAL, ATTITUDE, 20_000) == M.MAV_RESULT_ACCEPTED
        )
        assert per_sim_second(gcs, "ATTITUDE", 4.0) == pytest.approx(50.0, rel=0.05)
        gcs.close()


def test_the_wall_cap_holds_a_fast_simulation_to_the_cap() -> None:
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", "200") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        only(gcs, ATTITUDE)
        att = gcs.collect(["ATTITUDE"], 20.0)
        sim_s = (att[-1].time_boot_ms - att[0].time_boot_ms) / 1000
        # 20 Hz of simulated time: 4000 Hz of wall time at 200x, if the machine kept up; the
        # cap (200 Hz of wall time) leaves fewer than 20 per simulated second, never more.
        assert len(att) <= 20 * sim_s * 1.05 + 2
        gcs.close()
