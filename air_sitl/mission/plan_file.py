"""Mission plan files: QGroundControl ``.plan`` JSON and the ``QGC WPL 110`` text format.

The public entry points; the formats themselves are in :mod:`air_sitl.mission.plan_json` and
:mod:`air_sitl.mission.wpl`.

``load_mission`` is what ``air-sitl fly PLAN`` calls: it picks the format by content, parses
it into a :class:`~air_sitl.mission.items.Mission` and validates it with the same rules a
MAVLink upload goes through (:mod:`air_sitl.mission.validate`). Every user error is a
:class:`~air_sitl.errors.PlanError` with one line: ``"<path>: item <i>: <what> (<value>)"``.

Conventions a Mission keeps, whatever file it came from:

- ``items[i]`` is MAVLink mission sequence ``i`` (PX4 numbering: no home item).
- DO_JUMP ``param1`` is the 0-based sequence index of the target. A ``.plan`` stores the target's
  ``doJumpId`` there (QGC writes ``doJumpId`` = the item's 1-based sequence number at save
  time); :func:`read_plan` resolves it to an index and :func:`write_plan` writes
  ``doJumpId = index + 1`` for every item and ``index + 1`` into DO_JUMP's ``param1``. A
  ``QGC WPL`` file numbers home as seq 0, so its DO_JUMP target ``s`` becomes index ``s - 1``.
  ``MissionItem.do_jump_id`` of every item read is ``index + 1``; the writer ignores the field.
- Fence polygons are runs of NAV_FENCE_POLYGON_VERTEX_* items whose ``param1`` is the vertex
  count (as MAVLink carries them), in file order, then circles (``param1`` = radius), then the
  breach return point. Rally points are NAV_RALLY_POINT items.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from air_sitl.errors import PlanError
from air_sitl.mission.items import (
    FENCE_CIRCLE_COMMANDS,
    FENCE_POLYGON_COMMANDS,
    MavCmd,
    Mission,
    MissionItem,
    MissionType,
)
from air_sitl.mission.plan_json import plan_and_labels, plan_document, plan_from_text
from air_sitl.mission.reading import PathLike, read_text
from air_sitl.mission.validate import MISSION_LEVEL, check_mission
from air_sitl.mission.wpl import wpl_from_text


def load_mission(path: PathLike, *, terrain: bool = False) -> Mission:
    """Read a ``.plan`` or ``QGC WPL 110`` file (chosen by content) and validate it
    (``terrain``: a terrain model is loaded, terrain-relative frames fly)."""
    text = read_text(path)
    if _is_wpl(text):
        mission, labels = wpl_from_text(text, path)
    else:
        mission, labels = plan_and_labels(text, path)
    validate_mission(mission, item_labels=labels, terrain=terrain)
    return mission


def _is_wpl(text: str) -> bool:
    """QGC WPL text: its first line that is neither blank nor a ``#`` comment is the header."""
    for line in text.splitlines():
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            return stripped.startswith("QGC WPL")
    return False


def read_plan(path: PathLike) -> Mission:
    """Parse a QGroundControl ``.plan`` file (structure only; :func:`load_mission` validates)."""
    return plan_from_text(read_text(path), path)


def read_wpl(path: PathLike) -> Mission:
    """Parse a ``QGC WPL 110`` text file (line 0 is home; structure only)."""
    return wpl_from_text(read_text(path), path)[0]


def validate_mission(
    mission: Mission, *, item_labels: Sequence[str] | None = None, terrain: bool = False
) -> None:
    """Raise :class:`PlanError` for the first problem of the mission, fence or rally list.

    ``item_labels[i]`` names mission item ``i`` in messages (default ``"item i"``);
    ``terrain``: terrain-relative frames are accepted (a terrain model is loaded).
    """
    _check_home(mission)
    lists = (
        (MissionType.MISSION, mission.items, item_labels or _default_labels(mission.items)),
        (MissionType.FENCE, mission.fence, _fence_labels(mission.fence)),
        (MissionType.RALLY, mission.rally, [f"rally point {i}" for i in range(len(mission.rally))]),
    )
    for mission_type, items, labels in lists:
        if mission_type is not MissionType.MISSION and not items:
            continue
        problem = check_mission(items, mission_type, terrain=terrain)
        if problem is None:
            continue
        if problem.index == MISSION_LEVEL:
            raise PlanError(f"{mission.source}: {problem.message}")
        raise PlanError(f"{mission.source}: {labels[problem.index]}: {problem.message}")


def _check_home(mission: Mission) -> None:
    home = mission.planned_home
    if home is None:
        return
    where = f"{mission.source}: planned home position"
    if not (math.isfinite(home.lat_deg) and -90.0 <= home.lat_deg <= 90.0):
        raise PlanError(f"{where}: latitude outside [-90, 90] degrees ({home.lat_deg})")
    if not (math.isfinite(home.lon_deg) and -180.0 <= home.lon_deg <= 180.0):
        raise PlanError(f"{where}: longitude outside [-180, 180] degrees ({home.lon_deg})")
    if not math.isfinite(home.alt_amsl_m):
        raise PlanError(f"{where}: altitude must be a finite number of metres ({home.alt_amsl_m})")


def plan_text(mission: Mission, *, path: PathLike | None = None) -> str:
    """The ``.plan`` JSON of a mission: sorted keys, 4-space indent, shortest float repr."""
    where = str(path) if path is not None else mission.source
    doc = plan_document(mission, where)
    return json.dumps(doc, indent=4, sort_keys=True, allow_nan=False, ensure_ascii=True) + "\n"


def write_plan(mission: Mission, path: PathLike) -> None:
    """Write ``mission`` as a ``.plan`` file (atomically: temporary name, then rename)."""
    text = plan_text(mission, path=path)
    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    try:
        tmp.write_text(text, encoding="utf-8", newline="\n")
        tmp.replace(target)
    except OSError as err:
        msg = f"{path}: cannot write the plan: {err.strerror}"
        raise PlanError(msg) from None


def _default_labels(items: Sequence[MissionItem]) -> list[str]:
    return [f"item {i}" for i in range(len(items))]


def _fence_labels(fence: Sequence[MissionItem]) -> list[str]:
    """Name fence items as the .plan does: ``geoFence polygon 1 vertex 2``, ``circle 0`` ..."""
    labels: list[str] = []
    polygons = circles = 0
    i = 0
    while i < len(fence):
        item = fence[i]
        count = item.param1
        if item.command in FENCE_POLYGON_COMMANDS and math.isfinite(count) and int(count) >= 1:
            for v in range(int(count)):
                labels.append(f"geoFence polygon {polygons} vertex {v}")
            polygons += 1
            i += int(count)
        elif item.command in FENCE_CIRCLE_COMMANDS:
            labels.append(f"geoFence circle {circles}")
            circles += 1
            i += 1
        elif item.command == MavCmd.NAV_FENCE_RETURN_POINT:
            labels.append("geoFence breachReturn")
            i += 1
        else:
            labels.append(f"fence item {i}")
            i += 1
    return labels[: len(fence)]
