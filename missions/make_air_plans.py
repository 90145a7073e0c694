"""Generate the scenario plans (``missions/*.plan``) and their README table: AIR's 12 and
our 6 over farmland (map letter A, with the figures of their urban counterparts).

Usage: python missions/make_air_plans.py [--out DIR] [--table]

Each plan: NAV_TAKEOFF toward the capture area, DO_CHANGE_SPEED to the scenario's ground speed
(paper distance / (paper images / 50 Hz)), a waypoint R 500 m before the start point S on the
line of the first capture leg (home, takeoff point, R and S are collinear, so the aircraft
arrives at S level and straight), IMAGE_START_CAPTURE (0.02 s) at S, the shape,
IMAGE_STOP_CAPTURE, NAV_RETURN_TO_LAUNCH. Lines are one straight leg of the paper's length;
rectangles (3:2, clockwise) start and end at the middle of their first side, with a perimeter of
the paper's distance plus what the aircraft cuts at the four corners; circles are one clockwise
NAV_LOITER_TURNS of radius distance / (2 pi), tangent to the run-in at S.
The output is deterministic (same bytes on every run).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from air_sitl.dataset.scenarios import SCENARIO_TABLE
from air_sitl.frames import GRAVITY_M_S2, ned2geodetic
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import write_plan
from air_sitl.state import GeoPoint

MISSIONS_DIR = Path(__file__).resolve().parent
CAMERA_RATE_HZ = 50.0
CAPTURE_INTERVAL_S = 0.02
BANK_DEG = 30.0  # bank the planner assumes in turns (for the corner allowance)
TAKEOFF_PITCH_DEG = 15.0  # QGC's default fixed-wing takeoff pitch
TAKEOFF_POINT_M = 1000.0  # home -> takeoff waypoint, along the first capture leg
HOME_TO_START_M = 3000.0  # home -> S: room to climb to 300 m before the run-in
RUN_IN_M = 500.0  # R -> S: straight, lined up with the first capture leg
RECT_ASPECT = 1.5  # rectangle side along the run-in / side across it
SPEED_TYPE_GROUND = 1.0  # DO_CHANGE_SPEED param1


@dataclass(frozen=True, slots=True)
class Site:
    """Where a map type's scenarios are flown."""

    description: str
    home: GeoPoint
    heading_deg: float  # direction of the run-in and of the first capture leg


SITES = {
    "F": Site(
        "Ocala National Forest, Florida, USA (near Juniper Springs): flat pine and scrub "
        "woodland; legs run east over the Juniper Prairie Wilderness",
        GeoPoint(lat_deg=29.1790, lon_deg=-81.7400, alt_amsl_m=20.0),
        90.0,
    ),
    "A": Site(
        "York County, Nebraska, USA: home at York Municipal Airport (KJYR); legs run north "
        "over centre-pivot and dryland quarter sections on the one-mile survey grid",
        GeoPoint(lat_deg=40.8968, lon_deg=-97.6227, alt_amsl_m=509.0),
        0.0,
    ),
    "U": Site(
        "Sacramento, California, USA: home at Sacramento Executive Airport (KSAC); legs run "
        "north over the Land Park, Curtis Park and Oak Park neighbourhoods toward downtown",
        GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0),
        0.0,
    ),
}

PAPER = SCENARIO_TABLE  # scenario -> (images at 50 Hz, distance of the captured part in m)


@dataclass(frozen=True, slots=True)
class Scenario:
    """One planned scenario with the figures the README table shows."""

    name: str
    mission: Mission
    speed_m_s: float
    planned_length_m: float  # polyline / circle from S around the shape to the stop
    expected_flown_m: float  # planned length minus the corners the aircraft cuts
    paper_images: int
    paper_distance_m: float

    @property
    def expected_images(self) -> int:
        """Frames at 50 Hz over the expected flown length at the planned speed."""
        return round(self.expected_flown_m / self.speed_m_s * CAMERA_RATE_HZ)


def turn_radius_m(speed_m_s: float) -> float:
    """Radius of a level turn at BANK_DEG."""
    return speed_m_s**2 / (GRAVITY_M_S2 * math.tan(math.radians(BANK_DEG)))


def corner_cut_m(speed_m_s: float) -> float:
    """How much shorter a 90 degree corner is flown as an arc than planned as two legs."""
    r = turn_radius_m(speed_m_s)
    return 2.0 * r - 0.5 * math.pi * r


def _round7(x: float) -> float:
    """Degrees to 1e-7 (MAVLink's degE7), so uploads carry the plan's exact coordinates."""
    return round(x, 7)


def build(name: str) -> Scenario:
    """The plan of one scenario, e.g. ``"FR-300"``."""
    images, distance = PAPER[name]
    site = SITES[name[0]]
    shape = name[1]
    alt = float(name.split("-")[1])
    speed = round(distance / (images / CAMERA_RATE_HZ), 2)

    psi = math.radians(site.heading_deg)
    ahead = (math.cos(psi), math.sin(psi))  # (north, east) unit vector of the first leg
    right = (-math.sin(psi), math.cos(psi))  # clockwise side

    def at(forward_m: float, right_m: float) -> tuple[float, float]:
        """A point forward/right of home in the scenario's frame, as (lat, lon)."""
        n = forward_m * ahead[0] + right_m * right[0]
        e = forward_m * ahead[1] + right_m * right[1]
        lat, lon, _ = ned2geodetic(n, e, 0.0, site.home.lat_deg, site.home.lon_deg, 0.0)
        return _round7(lat), _round7(lon)

    def waypoint(forward_m: float, right_m: float) -> MissionItem:
        lat, lon = at(forward_m, right_m)
        return MissionItem(
            command=MavCmd.NAV_WAYPOINT,
            frame=MavFrame.GLOBAL_RELATIVE_ALT,
            param4=math.nan,
            lat_deg=lat,
            lon_deg=lon,
            alt_m=alt,
        )

    def capture(command: int, interval_s: float, images: float) -> MissionItem:
        """IMAGE_START_CAPTURE / IMAGE_STOP_CAPTURE of camera 0, no position (QGC: null)."""
        return MissionItem(
            command=command,
            frame=MavFrame.MISSION,
            param1=0.0,
            param2=interval_s,
            param3=images,
            param4=math.nan,
            lat_deg=math.nan,
            lon_deg=math.nan,
            alt_m=math.nan,
        )

    t_lat, t_lon = at(TAKEOFF_POINT_M, 0.0)
    s = HOME_TO_START_M  # S is at (s, 0)
    items = [
        MissionItem(
            command=MavCmd.NAV_TAKEOFF,
            frame=MavFrame.GLOBAL_RELATIVE_ALT,
            param1=TAKEOFF_PITCH_DEG,
            param4=math.nan,
            lat_deg=t_lat,
            lon_deg=t_lon,
            alt_m=alt,
        ),
        MissionItem(
            command=MavCmd.DO_CHANGE_SPEED,
            frame=MavFrame.MISSION,
            param1=SPEED_TYPE_GROUND,
            param2=speed,
            param3=-1.0,
            param4=0.0,
        ),
        waypoint(s - RUN_IN_M, 0.0),
        waypoint(s, 0.0),
        capture(MavCmd.IMAGE_START_CAPTURE, CAPTURE_INTERVAL_S, 0.0),
    ]
    if shape == "L":
        items.append(waypoint(s + distance, 0.0))
        planned = flown = distance
    elif shape == "R":
        cut = corner_cut_m(speed)
        perimeter = distance + 4.0 * cut
        across = perimeter / (2.0 * (1.0 + RECT_ASPECT))
        along = RECT_ASPECT * across
        half = along / 2.0
        items += [
            waypoint(s + half, 0.0),
            waypoint(s + half, across),
            waypoint(s - half, across),
            waypoint(s - half, 0.0),
            waypoint(s, 0.0),
        ]
        planned = perimeter
        flown = perimeter - 4.0 * cut
    elif shape == "C":
        radius = round(distance / (2.0 * math.pi), 1)
        c_lat, c_lon = at(s, radius)
        items.append(
            MissionItem(
                command=MavCmd.NAV_LOITER_TURNS,
                frame=MavFrame.GLOBAL_RELATIVE_ALT,
                param1=1.0,
                param2=0.0,
                param3=radius,  # positive: clockwise
                param4=0.0,
                lat_deg=c_lat,
                lon_deg=c_lon,
                alt_m=alt,
            )
        )
        planned = flown = 2.0 * math.pi * radius
    else:  # pragma: no cover - PAPER has only L, R, C
        raise ValueError(name)
    items += [
        capture(MavCmd.IMAGE_STOP_CAPTURE, math.nan, math.nan),
        MissionItem(command=MavCmd.NAV_RETURN_TO_LAUNCH, frame=MavFrame.MISSION, param4=0.0),
    ]
    mission = Mission(
        items=tuple(dataclasses.replace(it, do_jump_id=i + 1) for i, it in enumerate(items)),
        planned_home=site.home,
        cruise_speed_m_s=speed,
        source=f"missions/{name}.plan",
        name=name,
    )
    return Scenario(name, mission, speed, planned, flown, images, distance)


def table(scenarios: list[Scenario]) -> str:
    """The README's markdown table of planned versus paper figures."""
    rows = [
        "| scenario | paper images | paper distance m | paper speed m/s | planned capture "
        "length m | expected flown m | planned speed m/s | expected images |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for sc in scenarios:
        paper_speed = sc.paper_distance_m / (sc.paper_images / CAMERA_RATE_HZ)
        rows.append(
            f"| {sc.name} | {sc.paper_images} | {sc.paper_distance_m:.0f} | {paper_speed:.2f} | "
            f"{sc.planned_length_m:.0f} | {sc.expected_flown_m:.0f} | {sc.speed_m_s:.2f} | "
            f"{sc.expected_images} |"
        )
    return "\n".join(rows)


def main(out: Path, print_table: bool) -> int:
    """Write the 18 plans into ``out``; print the README table when asked."""
    out.mkdir(parents=True, exist_ok=True)
    scenarios = [build(name) for name in PAPER]
    for sc in scenarios:
        write_plan(sc.mission, out / f"{sc.name}.plan")
    if print_table:
        print(table(scenarios))
    return 0


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=MISSIONS_DIR, help="output folder")
    parser.add_argument("--table", action="store_true", help="print the README table")
    args = parser.parse_args()
    sys.exit(main(args.out, args.table))
