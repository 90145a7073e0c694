"""pytest plugin of air-sitl: a served vehicle for your own tests.

Installed with air-sitl (entry point ``pytest11``), so any test can ask for the fixture::

    def test_my_ground_station_sees_the_vehicle(air_sitl_vehicle):
        link = mavutil.mavlink_connection(air_sitl_vehicle.pymavlink_url)
        ...

``air_sitl_vehicle`` starts ``air-sitl serve`` as a real process on free 127.0.0.1 ports,
with MAVLink on UDP and TCP and a zenoh listener, and stops it after the test. Serve's own
options come from the ``air_sitl_serve`` marker::

    @pytest.mark.air_sitl_serve("--plan", "missions/UC-200.plan", "--speed", "10")
    def test_flies_my_plan(air_sitl_vehicle): ...

A vehicle that does not exit cleanly when stopped (exit code other than 0) fails the test.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from air_sitl.testing.served import ServedVehicle, served_vehicle

MARKER = "air_sitl_serve"


def pytest_configure(config: pytest.Config) -> None:
    """Declare the marker (so ``--strict-markers`` accepts it)."""
    config.addinivalue_line(
        "markers", f"{MARKER}(*args): options of `air-sitl serve` for the air_sitl_vehicle fixture"
    )


@pytest.fixture
def air_sitl_vehicle(request: pytest.FixtureRequest) -> Iterator[ServedVehicle]:
    """A running ``air-sitl serve`` on free loopback ports: MAVLink (UDP, TCP) and zenoh."""
    marker = request.node.get_closest_marker(MARKER)
    args = [str(a) for a in marker.args] if marker is not None else []
    with served_vehicle(*args) as vehicle:
        yield vehicle
        code = vehicle.stop()
        if code != 0:
            _out, err = vehicle.output()
            pytest.fail(f"air-sitl serve exited with {code} when stopped:\n{err}", pytrace=False)
