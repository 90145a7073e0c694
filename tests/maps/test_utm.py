"""UTM maths against GDAL (the procedural maps and MapX/MapY depend on it)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rasterio.warp import transform as warp_transform

from air_sitl.maps.utm import latlon2utm, utm2latlon, utm_zone_of


@settings(max_examples=60, deadline=None)
@given(st.floats(-79.0, 83.0), st.floats(-179.9, 179.9))
def test_forward_matches_gdal_and_inverts(lat: float, lon: float) -> None:
    zone = utm_zone_of(lat, lon)
    e, n = latlon2utm(lat, lon, zone)
    xs, ys = warp_transform("EPSG:4326", f"EPSG:{zone.epsg}", [lon], [lat])
    assert e == pytest.approx(xs[0], abs=1e-3)
    assert n == pytest.approx(ys[0], abs=1e-3)
    lat2, lon2 = utm2latlon(e, n, zone)
    assert lat2 == pytest.approx(lat, abs=1e-9)
    assert lon2 == pytest.approx(lon, abs=1e-9)


def test_zones() -> None:
    assert utm_zone_of(54.69, 25.28).epsg == 32635
    assert utm_zone_of(-33.9, 151.2).epsg == 32756
