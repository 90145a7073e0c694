"""MAVSDK in the tests: a ground station on a vehicle."""

from __future__ import annotations

import contextlib
import time
from collections.abc import AsyncIterator, Awaitable, Callable
from typing import TypeVar

from mavsdk.asyncio import ComponentType, Configuration, Mavsdk, System
from mavsdk.asyncio.plugins.action import ActionError
from mavsdk.asyncio.plugins.mission_raw import MissionRawError

T = TypeVar("T")


@contextlib.asynccontextmanager
async def ground_station(port: int, *, timeout_s: float) -> AsyncIterator[System]:
    """MAVSDK as a ground station listening on UDP ``port``: the first autopilot it hears."""
    config = Configuration.create_with_component_type(ComponentType.GROUND_STATION)
    async with Mavsdk(config) as sdk:
        await sdk.add_any_connection(f"udpin://127.0.0.1:{port}")
        system = await sdk.first_autopilot(timeout_s=timeout_s)
        assert system is not None, "MAVSDK found no autopilot"
        yield system


async def until_answered(call: Callable[[], Awaitable[T]], *, timeout_s: float) -> T:
    """``await call()`` again while MAVSDK reports a TIMEOUT (its transfers give up after about
    2 s of silence: a vehicle starved for seconds on a loaded machine), within ``timeout_s``;
    any other failure at once. A ground station's operator does the same: uploads again."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            return await call()
        except (MissionRawError, ActionError) as err:
            if err.result.name != "TIMEOUT" or time.monotonic() >= deadline:
                raise
