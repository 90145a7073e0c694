"""Where the sun stands for an aerial survey: elevation and azimuth from date, solar time and
latitude (NOAA's low-precision solar equations: declination from the fractional year).

The time is *local solar* time (noon = the sun due south or north), so longitude and the
equation of time drop out; NOAA quotes about 0.5 degrees accuracy, far below what a shadow on a
0.5 m pixel shows.
"""

from __future__ import annotations

import datetime as dt
import math


def declination_rad(day_of_year: int, solar_hour: float) -> float:
    """Solar declination (radians) on a day of the year (1..366) at a solar hour (NOAA)."""
    g = 2.0 * math.pi / 365.0 * (day_of_year - 1 + (solar_hour - 12.0) / 24.0)
    return (
        0.006918
        - 0.399912 * math.cos(g)
        + 0.070257 * math.sin(g)
        - 0.006758 * math.cos(2 * g)
        + 0.000907 * math.sin(2 * g)
        - 0.002697 * math.cos(3 * g)
        + 0.00148 * math.sin(3 * g)
    )


def sun_position(iso_date: str, solar_hour: float, lat_deg: float) -> tuple[float, float]:
    """(azimuth clockwise from north, elevation) in degrees of the sun on ``iso_date``
    (YYYY-MM-DD) at ``solar_hour`` local solar time seen from latitude ``lat_deg``."""
    day = dt.date.fromisoformat(iso_date).timetuple().tm_yday
    decl = declination_rad(day, solar_hour)
    phi = math.radians(lat_deg)
    hour_angle = math.radians(15.0 * (solar_hour - 12.0))
    sin_el = math.sin(phi) * math.sin(decl) + math.cos(phi) * math.cos(decl) * math.cos(hour_angle)
    elevation = math.degrees(math.asin(max(-1.0, min(1.0, sin_el))))
    # Azimuth from north, clockwise: east in the morning (negative hour angle), south at noon
    # north of the tropics.
    az = math.atan2(
        math.sin(hour_angle),
        math.cos(hour_angle) * math.sin(phi) - math.tan(decl) * math.cos(phi),
    )
    return (math.degrees(az) + 180.0) % 360.0, elevation
