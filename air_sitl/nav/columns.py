"""The onboard estimate as CSV columns: what frames.csv and trajectory.csv append (--nav ekf).

One home for the columns and their formatting, read by both writers (the archive's and the
trajectory's), which never import each other.
"""

from __future__ import annotations

from air_sitl.state import NavEstimate

# The onboard estimate (``--nav ekf``), appended to frames.csv and trajectory.csv; with
# ``--nav truth`` the files keep their columns of before (byte-identical archives).
NAV_COLUMNS: tuple[str, ...] = (
    "nav_east_m",
    "nav_north_m",
    "nav_up_m",
    "nav_lat_deg",
    "nav_lon_deg",
    "nav_alt_amsl_m",
    "nav_std_h_m",
)


# NAV_COLUMNS' formats, in one ``%`` call (the same text as f-string specs of these letters).
NAV_FORMAT = "%.4f,%.4f,%.4f,%.9f,%.9f,%.4f,%.4f"


def nav_values(est: NavEstimate) -> tuple[float, float, float, float, float, float, float]:
    """The NAV_COLUMNS' values of an estimate, in NAV_FORMAT's order."""
    n, e, d = est.pos_ned_m
    return (e, n, -d, est.lat_deg, est.lon_deg, est.alt_amsl_m, est.std_h_m)


def nav_fields(est: NavEstimate | None) -> str:
    """The NAV_COLUMNS of one row (empty fields before the filter has a position)."""
    if est is None:
        return ",,,,,,"
    return NAV_FORMAT % nav_values(est)
