"""Waiting on MAVSDK for what it reports a moment after the event a test follows."""

from __future__ import annotations

from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync


async def finished_within(
    mission: MissionRawAsync, telemetry: TelemetryAsync, positions: int = 10
) -> bool:
    """MAVSDK's ``is_mission_finished`` within ``positions`` position messages.

    MAVSDK reports progress (total, total) on the last MISSION_ITEM_REACHED and "finished" on
    the MISSION_CURRENT (state COMPLETE) sent right after it, as PX4 orders them: asked the
    moment progress reaches the total, it can still say no; a position message later it must
    say yes.
    """
    if await mission.is_mission_finished():
        return True
    async for _ in telemetry.subscribe_position():
        if await mission.is_mission_finished():
            return True
        positions -= 1
        if positions <= 0:
            return False
    return False
