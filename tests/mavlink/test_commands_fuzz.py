"""Every COMMAND_LONG gets exactly one COMMAND_ACK, whatever its parameters."""

from __future__ import annotations

import time
from collections.abc import Iterator

import pytest
from gcs import SAFETY_S, Gcs
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from inproc import Vehicle, running_vehicle

from air_sitl.state import GeoPoint

HANDLED = [20, 22, 176, 178, 192, 224, 300, 400, 410, 511, 512, 520, 521, 2000, 2001, 246, 519]


@pytest.fixture(scope="module")
def vehicle_gcs() -> Iterator[tuple[Vehicle, Gcs]]:
    home = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
    with running_vehicle(["udpin:127.0.0.1:0"], home, speed=5.0) as vehicle:
        port = vehicle.endpoint.links[0].local_address[1]
        gcs = Gcs(f"udpout:127.0.0.1:{port}")
        gcs.connect()
        yield vehicle, gcs
        gcs.close()


floats = st.one_of(
    st.floats(width=32),
    st.sampled_from([0.0, 1.0, -1.0, 4.0, 148.0, 242.0, 30.0, 1e9]),
)


@pytest.mark.integration
@settings(max_examples=80, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    command=st.one_of(st.sampled_from(HANDLED), st.integers(0, 65535)),
    params=st.lists(floats, min_size=7, max_size=7),
)
def test_every_command_is_acknowledged(
    vehicle_gcs: tuple[Vehicle, Gcs], command: int, params: list[float]
) -> None:
    vehicle, gcs = vehicle_gcs
    errors = vehicle.endpoint.io_errors
    gcs.conn.mav.command_long_send(1, 1, command, 0, *params)
    deadline = time.monotonic() + SAFETY_S
    ack = None
    while time.monotonic() < deadline and ack is None:
        msg = gcs.recv(["COMMAND_ACK"], 1.0)
        if msg is not None and msg.command == command:
            ack = msg
    assert ack is not None, f"no COMMAND_ACK for {command} {params}"
    assert vehicle.endpoint.io_errors == errors
    assert vehicle.thread is not None and vehicle.thread.is_alive()
