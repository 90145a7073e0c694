"""A short capture flight for tests: seconds of CPU, a few hundred frames with --air-start."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import write_plan
from air_sitl.state import GeoPoint

# The camera of flights whose frames nobody looks at (the bus's, progress, disk space, eval's
# archives): 160 x 120 without noise, about a twentieth of the default frame's cost.
SMALL_CAMERA = ("--camera-width", "160", "--camera-height", "120", "--noise-sigma", "0")


def write_short_plan(
    path: Path,
    home: GeoPoint,
    *,
    leg_m: float = 100.0,
    alt_m: float = 200.0,
    leg: Literal["east", "north"] = "east",
    name: str | None = None,
    lead_m: float = 0.0,
) -> Path:
    """Take-off, a waypoint 300 m out, IMAGE_START, a capture leg, IMAGE_STOP, one more waypoint.

    The capture leg of ``leg_m`` runs ``leg`` (about 330 frames per 100 m at 15 m/s);
    ``lead_m`` > 0 puts a leg that long (and its waypoint) before IMAGE_START.
    """

    def wp(along_m: float, out_m: float) -> MissionItem:
        n, e = (out_m, along_m) if leg == "east" else (along_m, out_m)
        lat, lon, _ = ned2geodetic(n, e, 0.0, home.lat_deg, home.lon_deg, 0.0)
        return MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=lat, lon_deg=lon, alt_m=alt_m)

    items = (
        MissionItem(command=MavCmd.NAV_TAKEOFF, param1=15.0, lat_deg=home.lat_deg,
                    lon_deg=home.lon_deg, alt_m=alt_m),
        wp(0.0, 300.0),
        *((wp(lead_m, 300.0),) if lead_m > 0 else ()),
        MissionItem(command=MavCmd.IMAGE_START_CAPTURE, frame=MavFrame.MISSION, param2=0.02),
        wp(lead_m + leg_m, 300.0),
        MissionItem(command=MavCmd.IMAGE_STOP_CAPTURE, frame=MavFrame.MISSION),
        wp(lead_m + leg_m + 60.0, 300.0),
    )  # fmt: skip
    mission = Mission(items=items, planned_home=home, cruise_speed_m_s=15.0, name=name or path.stem)
    write_plan(mission, path)
    return path


PlanItem = tuple[int, int, float, float, float]  # command, frame, lat_deg, lon_deg, altitude m


def write_items_plan(path: Path, home: GeoPoint, items: list[PlanItem]) -> Path:
    """A ``.plan`` of plain items with its planned home at ``home``, cruise 15 m/s."""
    mission = Mission(
        items=tuple(
            MissionItem(command=cmd, frame=frame, lat_deg=lat, lon_deg=lon, alt_m=alt)
            for cmd, frame, lat, lon, alt in items
        ),
        planned_home=home,
        cruise_speed_m_s=15.0,
        name=path.stem,
    )
    write_plan(mission, path)
    return path
