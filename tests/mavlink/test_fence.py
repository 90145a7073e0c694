"""Geofence geometry: circles and polygons, inclusion and exclusion."""

from __future__ import annotations

from air_sitl.mavlink.fence import breach, zones_of
from air_sitl.mission.items import MavCmd, MissionItem

LAT, LON = 47.0, 8.0
D = 0.01  # about 1.1 km of latitude


def vertex(cmd: MavCmd, lat: float, lon: float, count: int = 4) -> MissionItem:
    return MissionItem(command=cmd, param1=count, lat_deg=lat, lon_deg=lon)


def square(cmd: MavCmd, half: float) -> list[MissionItem]:
    corners = ((-half, -half), (-half, half), (half, half), (half, -half))
    return [vertex(cmd, LAT + a, LON + b) for a, b in corners]


def test_inclusion_polygon_with_an_exclusion_circle() -> None:
    fence = [
        *square(MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION, D),
        MissionItem(
            command=MavCmd.NAV_FENCE_CIRCLE_EXCLUSION,
            param1=200.0,
            lat_deg=LAT + D / 2,
            lon_deg=LON,
        ),
        MissionItem(command=MavCmd.NAV_FENCE_RETURN_POINT, lat_deg=LAT, lon_deg=LON),
    ]
    zones = zones_of(fence)
    assert len(zones) == 2
    assert breach(zones, LAT, LON) is None
    assert breach(zones, LAT + 2 * D, LON) == "outside the inclusion fence"
    assert breach(zones, LAT + D / 2 + 0.001, LON) == "inside an exclusion zone"


def test_several_inclusion_zones_allow_any_of_them() -> None:
    fence = [
        MissionItem(
            command=MavCmd.NAV_FENCE_CIRCLE_INCLUSION, param1=300.0, lat_deg=LAT, lon_deg=LON
        ),
        MissionItem(
            command=MavCmd.NAV_FENCE_CIRCLE_INCLUSION, param1=300.0, lat_deg=LAT + D, lon_deg=LON
        ),
    ]
    zones = zones_of(fence)
    assert breach(zones, LAT + 0.002, LON) is None
    assert breach(zones, LAT + D - 0.002, LON) is None
    assert breach(zones, LAT + D / 2, LON) is not None
    assert breach((), LAT, LON) is None  # no fence, no breach


def test_exclusion_polygon() -> None:
    zones = zones_of(square(MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION, D / 4))
    assert breach(zones, LAT, LON) == "inside an exclusion zone"
    assert breach(zones, LAT + D, LON) is None
