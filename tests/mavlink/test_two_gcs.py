"""Two ground stations with the same ids (QGroundControl and MAVProxy: both 255/190) on two
links: PX4 keeps mission transfers per link, one upload at a time, and answers a second
uploader with an error without disturbing the first."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from gcs import Gcs
from inproc import running_vehicle
from pymavlink import mavutil

from air_sitl.mavlink.codec import from_mission_message
from air_sitl.mavlink.messages import MissionItemMessage
from air_sitl.mission.items import MavCmd, MissionItem, MissionType
from air_sitl.state import GeoPoint

M = mavutil.mavlink
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
pytestmark = pytest.mark.integration


def waypoints(n: int, north_deg: float = 0.001) -> list[MissionItem]:
    return [
        MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            lat_deg=HOME.lat_deg + north_deg * (i + 1),
            lon_deg=HOME.lon_deg,
            alt_m=50.0,
        )
        for i in range(n)
    ]


@pytest.fixture
def qgc_and_mavproxy() -> Iterator[tuple[Gcs, Gcs, object]]:
    links = ["udpin:127.0.0.1:0", "udpin:127.0.0.1:0"]
    with running_vehicle(links, HOME, speed=1.0) as vehicle:
        ports = [link.local_address[1] for link in vehicle.endpoint.links]
        qgc, mavproxy = (Gcs(f"udpout:127.0.0.1:{p}") for p in ports)  # both 255/190
        qgc.connect()
        mavproxy.connect()
        yield qgc, mavproxy, vehicle
        qgc.close()
        mavproxy.close()


def test_a_second_uploader_with_the_same_ids_is_denied_and_the_first_completes(
    qgc_and_mavproxy: tuple[Gcs, Gcs, object],
) -> None:
    qgc, mavproxy, vehicle = qgc_and_mavproxy
    first, second = waypoints(3), waypoints(2, north_deg=0.002)
    qgc.conn.mav.mission_count_send(1, 1, len(first), 0)
    request = qgc.recv(["MISSION_REQUEST_INT"])
    assert request is not None and request.seq == 0
    # MAVProxy (same ids, other link) starts its own upload meanwhile: refused, on its link.
    mavproxy.drain()
    assert mavproxy.upload(second) == M.MAV_MISSION_DENIED
    # QGC's upload goes on undisturbed: its requests come to it, and it completes.
    for seq in range(len(first)):
        if seq > 0:
            request = qgc.recv(["MISSION_REQUEST_INT", "MISSION_ACK"])
            assert request.get_type() == "MISSION_REQUEST_INT", request
            assert request.seq == seq
        item = MissionItemMessage(seq=seq, item=first[seq])
        qgc.conn.mav.send(from_mission_message(item, 1, 1))
    ack = qgc.recv(["MISSION_ACK"])
    assert ack.type == M.MAV_MISSION_ACCEPTED
    stored = vehicle.endpoint.protocol.items(MissionType.MISSION)  # type: ignore[attr-defined]
    assert [i.lat_deg for i in stored] == pytest.approx([i.lat_deg for i in first])
    # Now MAVProxy may upload; QGC hears none of its transfer.
    qgc.drain()
    assert mavproxy.upload(second) == M.MAV_MISSION_ACCEPTED
    mavproxy.download()
    heard = qgc.collect(["MISSION_REQUEST_INT", "MISSION_ACK", "MISSION_COUNT"], 1.0)
    assert heard == []


def test_downloads_on_two_links_do_not_mix(qgc_and_mavproxy: tuple[Gcs, Gcs, object]) -> None:
    qgc, mavproxy, _vehicle = qgc_and_mavproxy
    items = waypoints(4)
    assert qgc.upload(items) == M.MAV_MISSION_ACCEPTED
    mavproxy.drain()
    assert len(qgc.download()) == 4
    assert mavproxy.collect(["MISSION_COUNT", "MISSION_ITEM_INT"], 1.0) == []
    assert len(mavproxy.download()) == 4
