"""WGS84 <-> UTM (transverse Mercator, Krueger series to order n^4: sub-millimetre in a zone).

Procedural maps live in the UTM zone of their home so that a ``map make`` GeoTIFF of the same
map (EPSG 326zz/327zz) has exactly the same ground coordinates; pure maths, no GDAL.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from air_sitl.frames import WGS84_A_M, WGS84_F

_K0 = 0.9996
_FALSE_EASTING_M = 500_000.0
_FALSE_NORTHING_SOUTH_M = 10_000_000.0

_N = WGS84_F / (2.0 - WGS84_F)
_A_RECT = WGS84_A_M / (1.0 + _N) * (1.0 + _N**2 / 4.0 + _N**4 / 64.0)
_ALPHA = (
    _N / 2 - 2 * _N**2 / 3 + 5 * _N**3 / 16 + 41 * _N**4 / 180,
    13 * _N**2 / 48 - 3 * _N**3 / 5 + 557 * _N**4 / 1440,
    61 * _N**3 / 240 - 103 * _N**4 / 140,
    49561 * _N**4 / 161280,
)
_BETA = (
    _N / 2 - 2 * _N**2 / 3 + 37 * _N**3 / 96 - _N**4 / 360,
    _N**2 / 48 + _N**3 / 15 - 437 * _N**4 / 1440,
    17 * _N**3 / 480 - 37 * _N**4 / 840,
    4397 * _N**4 / 161280,
)
_E = math.sqrt(WGS84_F * (2.0 - WGS84_F))


@dataclass(frozen=True, slots=True)
class UtmZone:
    """One UTM zone (1..60) and hemisphere."""

    zone: int
    north: bool

    @property
    def epsg(self) -> int:
        """EPSG code of the zone (WGS 84 / UTM)."""
        return (32600 if self.north else 32700) + self.zone

    @property
    def central_meridian_deg(self) -> float:
        """Longitude of the zone's central meridian."""
        return -183.0 + 6.0 * self.zone


def utm_zone_of(lat_deg: float, lon_deg: float) -> UtmZone:
    """The standard zone of a position (no Norway/Svalbard exceptions)."""
    zone = math.floor((lon_deg + 180.0) / 6.0) % 60 + 1
    return UtmZone(zone, lat_deg >= 0.0)


def latlon2utm(lat_deg: float, lon_deg: float, zone: UtmZone) -> tuple[float, float]:
    """Geodetic latitude/longitude to (easting_m, northing_m) in ``zone``."""
    phi = math.radians(lat_deg)
    lam = math.radians(lon_deg - zone.central_meridian_deg)
    sin_phi = math.sin(phi)
    t = math.sinh(math.atanh(sin_phi) - _E * math.atanh(_E * sin_phi))
    xi_p = math.atan2(t, math.cos(lam))
    eta_p = math.asinh(math.sin(lam) / math.hypot(t, math.cos(lam)))
    xi = xi_p
    eta = eta_p
    for j, a in enumerate(_ALPHA, start=1):
        xi += a * math.sin(2 * j * xi_p) * math.cosh(2 * j * eta_p)
        eta += a * math.cos(2 * j * xi_p) * math.sinh(2 * j * eta_p)
    easting = _FALSE_EASTING_M + _K0 * _A_RECT * eta
    northing = _K0 * _A_RECT * xi
    if not zone.north:
        northing += _FALSE_NORTHING_SOUTH_M
    return (easting, northing)


def utm2latlon(easting_m: float, northing_m: float, zone: UtmZone) -> tuple[float, float]:
    """Inverse of :func:`latlon2utm`: (lat_deg, lon_deg)."""
    north = northing_m if zone.north else northing_m - _FALSE_NORTHING_SOUTH_M
    xi = north / (_K0 * _A_RECT)
    eta = (easting_m - _FALSE_EASTING_M) / (_K0 * _A_RECT)
    xi_p = xi
    eta_p = eta
    for j, b in enumerate(_BETA, start=1):
        xi_p -= b * math.sin(2 * j * xi) * math.cosh(2 * j * eta)
        eta_p -= b * math.cos(2 * j * xi) * math.sinh(2 * j * eta)
    tau_p = math.sin(xi_p) / math.hypot(math.sinh(eta_p), math.cos(xi_p))
    lam = math.atan2(math.sinh(eta_p), math.cos(xi_p))
    # Solve tau from tau' (Karney 2011, Newton iteration).
    tau = tau_p
    for _ in range(5):
        sigma = math.sinh(_E * math.atanh(_E * tau / math.sqrt(1 + tau * tau)))
        tau_p_of_tau = tau * math.sqrt(1 + sigma * sigma) - sigma * math.sqrt(1 + tau * tau)
        d_tau = (
            (tau_p - tau_p_of_tau)
            / math.sqrt(1 + tau_p_of_tau**2)
            * (1 + (1 - _E * _E) * tau * tau)
            / ((1 - _E * _E) * math.sqrt(1 + tau * tau))
        )
        tau += d_tau
        if abs(d_tau) < 1e-14:
            break
    return (math.degrees(math.atan(tau)), math.degrees(lam) + zone.central_meridian_deg)
