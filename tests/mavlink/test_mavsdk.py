"""MAVSDK 4.x (native binding) flies the AIR rectangle and circle plans on our endpoint.

MAVSDK imports each AIR plan file as it is; what is flown is the same items on the course
drawn 40 % as large around home (:func:`course_at`): the climb, the turns, the loiter and the
return are all in it, and the flight (this test's CPU) about halves.
"""

from __future__ import annotations

import asyncio
import dataclasses
import math
import time
from pathlib import Path

import numpy as np
import pytest
from gcs import SAFETY_S, free_udp_port
from inproc import Vehicle, running_vehicle
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from mavsdk_wait import ground_station, until_answered

from air_sitl.frames import geodetic2ned, ned2geodetic
from air_sitl.mission.items import MissionItem, MissionType
from air_sitl.mission.plan_file import load_mission, write_plan

REPO = Path(__file__).resolve().parents[2]
# AIR's line (UL-300) is left out: its items (take-off, waypoints, camera trigger, RTL) are
# the rectangle's, fewer of them; what the line adds is minutes of flight, not a behaviour.
PLANS = {
    "rectangle": REPO / "missions" / "UR-300.plan",
    "circle": REPO / "missions" / "UC-300.plan",
}
SPEED = 100.0
COURSE_SCALE = 0.4
EARTH_RADIUS_M = 6_371_000.0
pytestmark = pytest.mark.integration


def course_at(plan: Path, out: Path, scale: float) -> Path:
    """``plan`` with every waypoint's north and east offsets from home times ``scale`` (the
    altitudes, the loiter radius and every other item as they are), written to ``out``."""
    mission = load_mission(plan)
    home = mission.planned_home
    assert home is not None

    def scaled(item: MissionItem) -> MissionItem:
        if not (item.is_nav and (item.lat_deg or item.lon_deg)):
            return item
        n, e, _ = geodetic2ned(item.lat_deg, item.lon_deg, 0.0, home.lat_deg, home.lon_deg, 0.0)
        lat, lon, _ = ned2geodetic(n * scale, e * scale, 0.0, home.lat_deg, home.lon_deg, 0.0)
        return dataclasses.replace(item, lat_deg=lat, lon_deg=lon)

    write_plan(dataclasses.replace(mission, items=tuple(map(scaled, mission.items))), out)
    return out


def _fields(item: object) -> tuple[object, ...]:
    names = ("seq", "frame", "command", "autocontinue", "x", "y")
    floats = ("param1", "param2", "param3", "param4", "z")
    rounded = tuple(
        None if math.isnan(getattr(item, n)) else round(getattr(item, n), 4) for n in floats
    )
    return tuple(getattr(item, n) for n in names) + rounded


def _track_errors(vehicle: Vehicle, received: list[tuple[float, float, float, int]]) -> float:
    """Largest distance from a received position to the nearest truth state sent before it
    arrived (the truth array is built once, after the flight stopped)."""
    states = vehicle.truth.states[: max(n for *_, n in received)]
    track = np.array([(s.lat_deg, s.lon_deg, s.alt_amsl_m) for s in states])
    worst = 0.0
    for lat, lon, alt, n in received:
        recent = track[max(0, n - 40_000) : n]
        north = np.radians(recent[:, 0] - lat) * EARTH_RADIUS_M
        east = np.radians(recent[:, 1] - lon) * EARTH_RADIUS_M * math.cos(math.radians(lat))
        up = recent[:, 2] - alt
        worst = max(worst, float(np.min(np.sqrt(north**2 + east**2 + up**2))))
    return worst


def _unplaced(item: object) -> tuple[object, ...]:
    """:func:`_fields` but the position (x, y)."""
    fields = _fields(item)
    return fields[:4] + fields[6:]


async def _fly(
    air_plan: Path,
    plan: Path,
    port: int,
    vehicle: Vehicle,
    received: list[tuple[float, float, float, int]],
) -> dict[str, float]:
    async with ground_station(port, timeout_s=SAFETY_S) as system:
        mission = MissionRawAsync(system)
        telemetry = TelemetryAsync(system)
        action = ActionAsync(system)

        air = (await mission.import_qgroundcontrol_mission(str(air_plan))).mission_items
        imported = await mission.import_qgroundcontrol_mission(str(plan))
        items = imported.mission_items
        assert len(items) >= 5
        assert [_unplaced(i) for i in items] == [_unplaced(i) for i in air]
        t0 = time.monotonic()
        await until_answered(lambda: mission.upload_mission(items), timeout_s=SAFETY_S)
        upload_s = time.monotonic() - t0
        downloaded = await mission.download_mission()
        assert [_fields(i) for i in downloaded] == [_fields(i) for i in items]
        stored = vehicle.endpoint.protocol.items(MissionType.MISSION)
        assert [i.command for i in stored] == [i.command for i in items]

        # Wait until the vehicle reports a usable position (GPS fix, home), as apps do.
        position = await asyncio.wait_for(anext(telemetry.subscribe_position()), SAFETY_S)
        assert math.isfinite(position.latitude_deg)

        await until_answered(action.arm, timeout_s=SAFETY_S)
        await until_answered(mission.start_mission, timeout_s=SAFETY_S)
        checked = {"positions": 0, "attitudes": 0, "max_att_err_deg": 0.0}

        async def check_telemetry() -> None:
            async for pos in telemetry.subscribe_position():
                # Kept with how many truth states existed when it arrived (compared later).
                where = (pos.latitude_deg, pos.longitude_deg, pos.absolute_altitude_m)
                received.append((*where, len(vehicle.truth.states)))

        async def check_attitude() -> None:
            async for att in telemetry.subscribe_attitude_euler():
                truth = vehicle.truth.by_ms.get(att.timestamp_us // 1000)
                if truth is None:
                    continue
                d = [
                    abs(math.remainder(att.roll_deg - math.degrees(truth.roll_rad), 360)),
                    abs(math.remainder(att.pitch_deg - math.degrees(truth.pitch_rad), 360)),
                    abs(math.remainder(att.yaw_deg - math.degrees(truth.yaw_rad), 360)),
                ]
                checked["attitudes"] += 1
                checked["max_att_err_deg"] = max(checked["max_att_err_deg"], *d)

        tasks = [asyncio.create_task(check_telemetry()), asyncio.create_task(check_attitude())]
        progress_seen = []

        async def follow() -> None:
            async for progress in mission.subscribe_mission_progress():
                progress_seen.append((progress.current, progress.total))
                if progress.total > 0 and progress.current == progress.total:
                    return

        await asyncio.wait_for(follow(), timeout=SAFETY_S)  # mission progress is the event

        assert await mission.is_mission_finished()  # from the moment progress reached the total
        for task in tasks:
            task.cancel()
        assert progress_seen[-1] == (len(items), len(items))
        assert len({c for c, _ in progress_seen}) >= 4, progress_seen
        checked["upload_s"] = upload_s
        checked["positions"] = len(received)
        return checked


@pytest.mark.parametrize("shape", sorted(PLANS))
def test_mavsdk_uploads_and_flies_the_air_plans(shape: str, tmp_path: Path) -> None:
    plan = course_at(PLANS[shape], tmp_path / PLANS[shape].name, COURSE_SCALE)
    home = load_mission(plan).planned_home
    assert home is not None
    port = free_udp_port()
    received: list[tuple[float, float, float, int]] = []
    with running_vehicle([f"udpout:127.0.0.1:{port}"], home, speed=SPEED) as vehicle:
        result = asyncio.run(_fly(PLANS[shape], plan, port, vehicle, received))
        assert vehicle.flight.autopilot.mission_completed
    result["max_pos_err_m"] = _track_errors(vehicle, received)
    assert result["positions"] > 20 and result["attitudes"] > 20, result
    assert result["max_pos_err_m"] < 0.5, result  # degE7 and mm: exact up to rounding
    assert result["max_att_err_deg"] < 0.01, result
