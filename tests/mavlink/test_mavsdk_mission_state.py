"""MAVSDK's mission state stays finished once finished (issue 33, point 9).

A MAVSDK script that follows ``subscribe_mission_progress`` to its total and then asks
``is_mission_finished()`` must hear yes, and keep hearing it through the return home and a
landing, until it uploads or starts a new mission. Twenty short missions are flown back to back
on one served vehicle (the first from the ground, the others from the loiter at home), the
state polled every 100 ms of wall time; how long the vehicle flies after each finish is counted
in simulated time (MAVSDK's attitude timestamps), so a busy machine changes the number of polls,
never the outcome.
"""

from __future__ import annotations

import asyncio
import contextlib
import time
from collections.abc import AsyncIterator, Callable
from pathlib import Path

import pytest
from gcs import SAFETY_S, free_udp_port, serve
from mavsdk.asyncio.plugins.action import ActionAsync
from mavsdk.asyncio.plugins.mission_raw import MissionRawAsync
from mavsdk.asyncio.plugins.telemetry import LandedState, TelemetryAsync
from mavsdk_wait import ground_station, until_answered
from short_plans import write_items_plan

from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd, MavFrame
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0)
MISSIONS = 20
SPEED = "100"
POLL_S = 0.1  # how often the script asks, in wall seconds
AFTER_FINISH_SIM_S = 5.0  # simulated time of RTL loiter watched after each finish
CLOCK_HZ = 2.0  # attitude messages per simulated second: the clock the watch reads
pytestmark = pytest.mark.integration


def _plan(path: Path) -> Path:
    """Two waypoints 200 m out, then RTL: under a minute of flight."""

    def wp(north_m: float, east_m: float) -> tuple[int, int, float, float, float]:
        lat, lon, _ = ned2geodetic(north_m, east_m, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        return (MavCmd.NAV_WAYPOINT, MavFrame.GLOBAL_RELATIVE_ALT, lat, lon, 60.0)

    rtl = (MavCmd.NAV_RETURN_TO_LAUNCH, MavFrame.MISSION, 0.0, 0.0, 0.0)
    return write_items_plan(path, HOME, [wp(200.0, 0.0), wp(200.0, 100.0), rtl])


class Watch:
    """Polls ``is_mission_finished`` while the vehicle flies; counts each "no"."""

    def __init__(self, mission: MissionRawAsync, telemetry: TelemetryAsync) -> None:
        self.mission = mission
        self.sim_us = 0  # the latest simulated time MAVSDK heard (attitude timestamps)
        self.landed = LandedState.UNKNOWN
        self.polls = 0
        self.unfinished = 0
        self._telemetry = telemetry

    @contextlib.asynccontextmanager
    async def following(self) -> AsyncIterator[Watch]:
        async def clock() -> None:
            async for att in self._telemetry.subscribe_attitude_euler():
                self.sim_us = max(self.sim_us, att.timestamp_us)

        async def landed() -> None:
            async for state in self._telemetry.subscribe_landed_state():
                self.landed = state

        await self._telemetry.set_rate_attitude_euler(CLOCK_HZ)  # the clock, cheaply
        tasks = [asyncio.create_task(clock()), asyncio.create_task(landed())]
        try:
            yield self
        finally:
            for task in tasks:
                task.cancel()

    async def poll_until(self, done: Callable[[], bool], min_polls: int = 3) -> None:
        """Ask at once, then every POLL_S, until ``done`` (and at least ``min_polls`` asks)."""
        start, deadline = self.polls, time.monotonic() + SAFETY_S
        while time.monotonic() < deadline:
            self.polls += 1
            self.unfinished += not await self.mission.is_mission_finished()
            if done() and self.polls - start >= min_polls:
                return
            await asyncio.sleep(POLL_S)
        raise AssertionError(f"the vehicle went silent (simulated time {self.sim_us} us)")

    def sim_seconds(self, seconds: float) -> Callable[[], bool]:
        """A condition true once ``seconds`` of simulated time have passed from now."""
        start = self.sim_us
        return lambda: self.sim_us - start >= seconds * 1e6


async def _to_total(mission: MissionRawAsync) -> tuple[int, int]:
    async for progress in mission.subscribe_mission_progress():
        if progress.total > 0 and progress.current == progress.total:
            return progress.current, progress.total
    raise AssertionError("mission progress ended")


async def _fly(port: int, plan: Path) -> Watch:
    async with ground_station(port, timeout_s=SAFETY_S) as system:
        mission, action = MissionRawAsync(system), ActionAsync(system)
        watch = Watch(mission, TelemetryAsync(system))
        items = (await mission.import_qgroundcontrol_mission(str(plan))).mission_items
        async with watch.following():
            for n in range(MISSIONS):
                await until_answered(lambda: mission.upload_mission(items), timeout_s=SAFETY_S)
                assert not await mission.is_mission_finished()  # a new mission: not yet
                if n == 0:
                    await until_answered(action.arm, timeout_s=SAFETY_S)
                await until_answered(mission.start_mission, timeout_s=SAFETY_S)
                total = await asyncio.wait_for(_to_total(mission), SAFETY_S)
                assert total == (len(items), len(items))
                # From the moment progress reaches its total: finished, through the RTL loiter.
                await watch.poll_until(watch.sim_seconds(AFTER_FINISH_SIM_S))
                assert watch.unfinished == 0, f"mission {n}: {watch.unfinished} polls said no"
            # ... and through a landing, until on the ground and a little after.
            await action.land()
            await watch.poll_until(lambda: watch.landed == LandedState.ON_GROUND)
            await watch.poll_until(watch.sim_seconds(2.0))
        return watch


def test_mavsdk_sees_each_mission_finished_from_its_total_until_the_next(tmp_path: Path) -> None:
    plan = _plan(tmp_path / "short-rtl.plan")
    port = free_udp_port()
    home = f"{HOME.lat_deg},{HOME.lon_deg},{HOME.alt_amsl_m}"
    with serve("--mavlink", f"udpout:127.0.0.1:{port}", "--home", home, "--speed", SPEED):
        watch = asyncio.run(_fly(port, plan))  # each wait in it is bounded
    assert watch.unfinished == 0, f"{watch.unfinished} of {watch.polls} polls said not finished"
    assert watch.polls >= MISSIONS * 3
    assert watch.landed == LandedState.ON_GROUND
