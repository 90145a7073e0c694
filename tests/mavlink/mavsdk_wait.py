"""MAVSDK in the tests: a ground station on a vehicle, and waiting on what MAVSDK reports a
moment after the event a test follows."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk, System
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync


@contextlib.asynccontextmanager
async def ground_station(port: int, *, timeout_s: float) -> AsyncIterator[System]:
    """MAVSDK as a ground station listening on UDP ``port``: the first autopilot it hears."""
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await sdk.first_autopilot(timeout_s=timeout_s)
        assert system is not None, "MAVSDK found no autopilot"
        yield system


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
