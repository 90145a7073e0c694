"""Mission item validation shared by the plan-file loader and MAVLink mission uploads.

Pure functions, no I/O: :func:`check_item` looks at one item, :func:`check_mission` at a whole
list (every item, then cross-item rules such as DO_JUMP targets). A problem comes back as an
:class:`ItemProblem` naming the ``MAV_MISSION_RESULT`` the MAVLink layer answers with and a
one-line message (what is wrong, what was expected, the value in parentheses) that the file
loader turns into a :class:`~air_sitl.errors.PlanError`.

DO_JUMP convention: in a :class:`~air_sitl.mission.items.Mission` (and in MAVLink), DO_JUMP's
``param1`` is the 0-based sequence index of the target item. Plan files store a QGC
``doJumpId`` there instead; :mod:`air_sitl.mission.plan_json` converts on read and write.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from air_sitl.errors import PlanError
from air_sitl.mission.geometry import next_nav_index
from air_sitl.mission.items import (
    FENCE_CIRCLE_COMMANDS,
    FENCE_COMMANDS,
    FENCE_POLYGON_COMMANDS,
    GLOBAL_FRAMES,
    MISSION_COMMANDS,
    NAV_COMMANDS,
    RALLY_COMMANDS,
    RELATIVE_FRAMES,
    SKIPPED_COMMANDS,
    TERRAIN_FRAMES,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
    MissionResult,
    MissionType,
)

# DO_* items carry no position; QGC writes them with MAV_FRAME_MISSION, others with a global frame.
DO_FRAMES = GLOBAL_FRAMES | {MavFrame.MISSION}

# Commands whose params 5..7 are a position the vehicle flies to, around, or keeps inside.
POSITION_COMMANDS = (
    (NAV_COMMANDS - {MavCmd.NAV_RETURN_TO_LAUNCH, MavCmd.NAV_DELAY})
    | FENCE_COMMANDS
    | RALLY_COMMANDS
)

# Known commands a fixed wing cannot fly safely, and why (refused, never skipped).
REFUSED_COMMANDS: dict[MavCmd, str] = {
    MavCmd.NAV_VTOL_TAKEOFF: "a fixed wing cannot take off vertically, expected NAV_TAKEOFF",
    MavCmd.NAV_VTOL_LAND: "a fixed wing cannot land vertically, expected NAV_LAND",
}

# Fence polygons and circles are 2-D: clients send any altitude (QGC 0, others NaN).
_ALTITUDE_UNUSED = frozenset(FENCE_POLYGON_COMMANDS + FENCE_CIRCLE_COMMANDS)

ALLOWED_COMMANDS: dict[MissionType, frozenset[MavCmd]] = {
    MissionType.MISSION: MISSION_COMMANDS,
    MissionType.FENCE: FENCE_COMMANDS,
    MissionType.RALLY: RALLY_COMMANDS,
}

# DO_CHANGE_SPEED param1: 0 airspeed, 1 ground speed, 2 climb speed, 3 descent speed.
SPEED_TYPES = frozenset({0.0, 1.0, 2.0, 3.0})
MISSION_LEVEL = -1  # ItemProblem.index of a problem with the whole list, not one item


@dataclass(frozen=True, slots=True, kw_only=True)
class ItemProblem:
    """Why an item (or a whole list, ``index == -1``) is refused.

    ``result`` names the MAV_MISSION_RESULT to answer a MAVLink upload with; ``message`` says
    what is wrong and what was expected, ending with the offending value in parentheses.
    """

    index: int
    result: str
    message: str

    @property
    def result_code(self) -> MissionResult:
        """The MAV_MISSION_RESULT value (KeyError for a name MAVLink does not have)."""
        return MissionResult[self.result.removeprefix("MAV_MISSION_")]


def command_name(command: int) -> str:
    """``NAV_WAYPOINT`` for 16; the number itself for commands this project does not know."""
    try:
        return MavCmd(command).name
    except ValueError:
        return str(command)


def frame_name(frame: int) -> str:
    """``GLOBAL_RELATIVE_ALT`` for 3; the number itself for unknown frames."""
    try:
        return MavFrame(frame).name
    except ValueError:
        return str(frame)


def _names(commands: frozenset[MavCmd]) -> str:
    return ", ".join(c.name for c in sorted(commands))


def _is_whole(x: float) -> bool:
    return math.isfinite(x) and x == int(x)


def check_item(
    item: MissionItem, index: int, mission_type: MissionType, *, terrain: bool = False
) -> ItemProblem | None:
    """The first problem of one item of a ``mission_type`` list, or None when it can be flown.

    ``terrain``: a terrain model is loaded (``--dem``), so terrain-relative frames fly.
    """

    def problem(result: str, message: str) -> ItemProblem:
        return _problem(index, result, message)

    allowed = ALLOWED_COMMANDS[mission_type]
    kind = mission_type.name.lower()
    if item.command not in allowed:
        name = command_name(item.command)
        if mission_type is MissionType.MISSION and item.command in REFUSED_COMMANDS:
            why = REFUSED_COMMANDS[MavCmd(item.command)]
            return problem("UNSUPPORTED", f"{name} cannot be flown: {why} ({item.command})")
        known = item.command in MavCmd._value2member_map_
        what = f"command {name} is not supported in a {kind} list" if known else "unknown command"
        return problem("UNSUPPORTED", f"{what}, expected one of {_names(allowed)} ({item.command})")
    cmd = MavCmd(item.command)

    # Frame.
    if item.frame in TERRAIN_FRAMES and not terrain:
        return problem(
            "UNSUPPORTED_FRAME",
            "terrain-relative frame is not supported (no terrain model: fly with --dem), "
            f"expected GLOBAL or GLOBAL_RELATIVE_ALT ({frame_name(item.frame)})",
        )
    if cmd in POSITION_COMMANDS:
        frames: frozenset[MavFrame] = GLOBAL_FRAMES | (TERRAIN_FRAMES if terrain else frozenset())
        expected = "GLOBAL, GLOBAL_RELATIVE_ALT or their _INT variants"
    else:  # DO_* items and RTL carry no position
        frames = DO_FRAMES
        expected = "MISSION, GLOBAL or GLOBAL_RELATIVE_ALT"
    if item.frame not in frames:
        return problem(
            "UNSUPPORTED_FRAME",
            f"frame not supported for {cmd.name}, expected {expected} ({frame_name(item.frame)})",
        )

    # Params 1..4 may be NaN (QGC's null, "unchanged"), never infinite.
    for n, value in enumerate((item.param1, item.param2, item.param3, item.param4), start=1):
        if math.isinf(value):
            return problem(f"INVALID_PARAM{n}", f"param{n} must be finite ({value})")

    # Position.
    if cmd in POSITION_COMMANDS:
        if not (math.isfinite(item.lat_deg) and -90.0 <= item.lat_deg <= 90.0):
            return problem(
                "INVALID_PARAM5_X", f"latitude outside [-90, 90] degrees ({item.lat_deg})"
            )
        if not (math.isfinite(item.lon_deg) and -180.0 <= item.lon_deg <= 180.0):
            return problem(
                "INVALID_PARAM6_Y", f"longitude outside [-180, 180] degrees ({item.lon_deg})"
            )
        if cmd not in _ALTITUDE_UNUSED and not math.isfinite(item.alt_m):
            return problem(
                "INVALID_PARAM7", f"altitude must be a finite number of metres ({item.alt_m})"
            )

    return _check_params(cmd, item, index)


def _problem(index: int, result: str, message: str) -> ItemProblem:
    return ItemProblem(index=index, result=f"MAV_MISSION_{result}", message=message)


def _check_params(cmd: MavCmd, item: MissionItem, index: int) -> ItemProblem | None:
    """Command-specific parameter rules."""

    def problem(result: str, message: str) -> ItemProblem:
        return _problem(index, result, message)

    if cmd is MavCmd.NAV_TAKEOFF and item.frame in RELATIVE_FRAMES and not item.alt_m > 0.0:
        return problem(
            "INVALID_PARAM7",
            f"takeoff altitude must be above home, expected > 0 m ({item.alt_m})",
        )
    if cmd is MavCmd.NAV_LOITER_TURNS and not (math.isfinite(item.param1) and item.param1 > 0):
        return problem("INVALID_PARAM1", f"loiter turns must be a number > 0 ({item.param1})")
    if cmd is MavCmd.NAV_LOITER_TIME and not (math.isfinite(item.param1) and item.param1 >= 0):
        return problem(
            "INVALID_PARAM1", f"loiter time must be a number of seconds >= 0 ({item.param1})"
        )
    if cmd is MavCmd.NAV_DELAY and not (math.isfinite(item.param1) and item.param1 >= 0):
        return problem(
            "INVALID_PARAM1",
            "delay must be a number of seconds >= 0 (a delay until a time of day, -1, is not "
            f"supported: the simulation has no clock of day) ({item.param1})",
        )
    if cmd is MavCmd.DO_SET_CAM_TRIGG_DIST and not (
        math.isfinite(item.param1) and item.param1 >= 0
    ):
        return problem(
            "INVALID_PARAM1",
            f"trigger distance must be a number of metres >= 0, 0 = stop ({item.param1})",
        )
    if cmd is MavCmd.DO_CHANGE_SPEED:
        if item.param1 not in SPEED_TYPES:
            return problem(
                "INVALID_PARAM1",
                "speed type must be 0 airspeed, 1 ground speed, 2 climb or 3 descent "
                f"({item.param1})",
            )
        if not (math.isfinite(item.param2) and (item.param2 > 0 or item.param2 == -1)):
            return problem(
                "INVALID_PARAM2",
                f"speed must be > 0 m/s, or -1 for no change ({item.param2})",
            )
    if cmd is MavCmd.DO_JUMP:
        if not (_is_whole(item.param1) and item.param1 >= 0):
            return problem(
                "INVALID_SEQUENCE",
                f"jump target must be an item index >= 0 ({item.param1})",
            )
        if not (_is_whole(item.param2) and item.param2 >= 0):
            return problem(
                "INVALID_PARAM2",
                f"jump repeat count must be a whole number >= 0 ({item.param2})",
            )
    if cmd is MavCmd.IMAGE_START_CAPTURE:
        if not (math.isfinite(item.param2) and item.param2 >= 0):
            return problem(
                "INVALID_PARAM2",
                f"capture interval must be a number of seconds >= 0 ({item.param2})",
            )
        if not (math.isnan(item.param3) or (_is_whole(item.param3) and item.param3 >= 0)):
            return problem(
                "INVALID_PARAM3",
                f"image count must be a whole number >= 0, 0 = until stopped ({item.param3})",
            )
    if cmd in (
        MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
        MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
    ) and not (_is_whole(item.param1) and item.param1 >= 3):
        return problem(
            "INVALID_PARAM1",
            f"polygon vertex count must be a whole number >= 3 ({item.param1})",
        )
    if cmd in (
        MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
        MavCmd.NAV_FENCE_CIRCLE_EXCLUSION,
    ) and not (math.isfinite(item.param1) and item.param1 > 0):
        return problem("INVALID_PARAM1", f"fence circle radius must be > 0 m ({item.param1})")
    return None


def check_mission(
    items: Sequence[MissionItem],
    mission_type: MissionType,
    *,
    allow_empty: bool = False,
    terrain: bool = False,
) -> ItemProblem | None:
    """The first problem of a whole list: every item, then cross-item rules; None when valid.

    A mission must contain at least one navigation item, unless ``allow_empty`` and the list is
    empty (a MAVLink upload of 0 items clears the vehicle's mission). Fence polygons must be
    runs of exactly ``param1`` vertices with the same command and count.
    """
    for index, item in enumerate(items):
        found = check_item(item, index, mission_type, terrain=terrain)
        if found is not None:
            return found
    if mission_type is MissionType.MISSION:
        return _check_mission_list(items, allow_empty=allow_empty)
    if mission_type is MissionType.FENCE:
        return _check_fence_list(items)
    return None


def _check_mission_list(items: Sequence[MissionItem], *, allow_empty: bool) -> ItemProblem | None:
    if not any(item.is_nav for item in items) and not (allow_empty and not items):
        return ItemProblem(
            index=MISSION_LEVEL,
            result="MAV_MISSION_INVALID",
            message=(
                "mission has no navigation item, expected at least one of "
                f"{_names(frozenset(c for c in MISSION_COMMANDS if c.name.startswith('NAV_')))} "
                f"({len(items)} items)"
            ),
        )
    for index, item in enumerate(items):
        if item.command != MavCmd.DO_JUMP:
            continue
        target = int(item.param1)
        if target >= len(items):
            return ItemProblem(
                index=index,
                result="MAV_MISSION_INVALID_SEQUENCE",
                message=(
                    f"jump target is not an item of this mission, expected 0..{len(items) - 1} "
                    f"({target})"
                ),
            )
        if target == index:
            return ItemProblem(
                index=index,
                result="MAV_MISSION_INVALID_SEQUENCE",
                message=f"jump target is the jump itself, expected another item ({target})",
            )
    return None


def _check_fence_list(items: Sequence[MissionItem]) -> ItemProblem | None:
    index = 0
    while index < len(items):
        first = items[index]
        if first.command not in FENCE_POLYGON_COMMANDS:
            index += 1
            continue
        count = int(first.param1)
        for j in range(index, index + count):
            if j >= len(items) or (items[j].command, items[j].param1) != (
                first.command,
                first.param1,
            ):
                got = "end of list" if j >= len(items) else command_name(items[j].command)
                return ItemProblem(
                    index=min(j, len(items) - 1),
                    result="MAV_MISSION_INVALID_PARAM1",
                    message=(
                        f"polygon starting at item {index} declares {count} vertices but vertex "
                        f"{j - index} is missing or differs ({got})"
                    ),
                )
        index += count
    return None


# PX4's feasibility check refuses to start such a mission (the upload itself is accepted).
TAKEOFF_NOT_FIRST = "Mission rejected: takeoff not first waypoint item"


def takeoff_order_problem(items: Sequence[MissionItem]) -> str:
    """PX4's rule: when the mission has a NAV_TAKEOFF, no navigation item comes before it
    (DO items and NAV_DELAY may). The STATUSTEXT reason, then where; '' when in order."""
    takeoff = next((i for i, it in enumerate(items) if it.command == MavCmd.NAV_TAKEOFF), -1)
    for index, item in enumerate(items[: max(0, takeoff)]):
        if item.is_nav and item.command != MavCmd.NAV_DELAY:
            return (
                f"{TAKEOFF_NOT_FIRST} (item {index} {command_name(item.command)} before "
                f"NAV_TAKEOFF at item {takeoff})"
            )
    return ""


def require_startable(mission: Mission) -> None:
    """Raise :class:`PlanError` when PX4 would refuse to start ``mission`` (the fly command)."""
    problem = takeoff_order_problem(mission.items)
    if problem:
        raise PlanError(f"{mission.source}: {problem}")


def item_warnings(items: Sequence[MissionItem]) -> list[str]:
    """One line per item flown differently from its definition, or skipped, and why."""
    out: list[str] = []
    flat = tuple(items)
    for index, item in enumerate(items):
        if item.command in SKIPPED_COMMANDS:
            why = SKIPPED_COMMANDS[MavCmd(item.command)]
            out.append(f"item {index}: {command_name(item.command)} skipped: {why}")
        elif item.command == MavCmd.NAV_LOITER_UNLIM and next_nav_index(flat, index + 1, {}) >= 0:
            out.append(
                f"item {index}: NAV_LOITER_UNLIM never ends (as in PX4): the items after it are "
                "not flown and the flight ends only at the time limit (--max-sim-time)"
            )
        elif item.command == MavCmd.NAV_SPLINE_WAYPOINT:
            out.append(
                f"item {index}: NAV_SPLINE_WAYPOINT flown as a waypoint (straight legs, no spline)"
            )
    return out


def mission_warnings(mission: Mission) -> list[str]:
    """What reading the plan found (mission notes), then the per-item warnings."""
    return [*mission.notes, *item_warnings(mission.items)]
