"""MAVSDK in the tests: a ground station on a vehicle."""

from __future__ import annotations

import contextlib
from collections.abc import AsyncIterator

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk, System


@contextlib.asynccontextmanager
async def ground_station(port: int, *, timeout_s: float) -> AsyncIterator[System]:
    """MAVSDK as a ground station listening on UDP ``port``: the first autopilot it hears."""
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await sdk.first_autopilot(timeout_s=timeout_s)
        assert system is not None, "MAVSDK found no autopilot"
        yield system
