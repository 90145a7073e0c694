"""Mission plan files: QGroundControl ``.plan`` JSON and the ``QGC WPL 110`` text format.

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

import dataclasses
import json
import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any, NoReturn

from air_sitl.errors import PlanError
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem, MissionType
from air_sitl.mission.validate import MISSION_LEVEL, check_mission
from air_sitl.state import GeoPoint

PathLike = str | os.PathLike[str]

PLAN_FILE_TYPE = "Plan"
PLAN_VERSION = 1
MISSION_VERSION = 2
FENCE_VERSION = 2
RALLY_VERSION = 2
FIRMWARE_PX4 = 12  # MAV_AUTOPILOT_PX4
VEHICLE_FIXED_WING = 1  # MAV_TYPE_FIXED_WING
HOVER_SPEED_M_S = 5.0  # QGC's default; unused by a fixed-wing, written because QGC expects it
GROUND_STATION = "air-sitl"
WPL_HEADER = "QGC WPL 110"
WPL_COLUMNS = (
    "seq",
    "current",
    "frame",
    "command",
    "param1",
    "param2",
    "param3",
    "param4",
    "x/latitude",
    "y/longitude",
    "z/altitude",
    "autocontinue",
)

_POLYGON_CMDS = (
    MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
    MavCmd.NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
)
_CIRCLE_CMDS = (MavCmd.NAV_FENCE_CIRCLE_INCLUSION, MavCmd.NAV_FENCE_CIRCLE_EXCLUSION)


# ---------------------------------------------------------------------------------------------
# Public API


def load_mission(path: PathLike) -> Mission:
    """Read a ``.plan`` or ``QGC WPL 110`` file (chosen by content) and validate it."""
    text = _read_text(path)
    if text.lstrip().startswith("QGC WPL"):
        mission, labels = _wpl_from_text(text, path)
    else:
        mission = _plan_from_text(text, path)
        labels = None
    validate_mission(mission, item_labels=labels)
    return mission


def read_plan(path: PathLike) -> Mission:
    """Parse a QGroundControl ``.plan`` file (structure only; :func:`load_mission` validates)."""
    return _plan_from_text(_read_text(path), path)


def read_wpl(path: PathLike) -> Mission:
    """Parse a ``QGC WPL 110`` text file (line 0 is home; structure only)."""
    return _wpl_from_text(_read_text(path), path)[0]


def validate_mission(mission: Mission, *, item_labels: Sequence[str] | None = None) -> None:
    """Raise :class:`PlanError` for the first problem of the mission, fence or rally list.

    ``item_labels[i]`` names mission item ``i`` in messages (default ``"item i"``).
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
        problem = check_mission(items, mission_type)
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
    doc = _plan_document(mission, where)
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


# ---------------------------------------------------------------------------------------------
# Reading helpers


def _read_text(path: PathLike) -> str:
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        msg = f"{path}: file not found"
        raise PlanError(msg) from None
    except IsADirectoryError:
        msg = f"{path}: is a folder, expected a .plan or QGC WPL file"
        raise PlanError(msg) from None
    except OSError as err:
        msg = f"{path}: cannot read: {err.strerror}"
        raise PlanError(msg) from None
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        msg = f"{path}: not a text file, expected UTF-8 JSON or QGC WPL (byte {err.start})"
        raise PlanError(msg) from None


def _type_name(value: object) -> str:
    return {
        dict: "object",
        list: "array",
        str: "string",
        bool: "boolean",
        int: "number",
        float: "number",
        type(None): "null",
    }.get(type(value), type(value).__name__)


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


class _Json:
    """Typed access to one JSON object, with errors naming the file, the place and the field."""

    def __init__(self, obj: object, path: PathLike, where: str, field_prefix: str = "") -> None:
        self.path = path
        self.where = where  # "item 3", "" for file level
        self.prefix = field_prefix  # "mission." for nested file-level fields
        if not isinstance(obj, dict):
            self.fail(f"expected a JSON object ({_type_name(obj)})")
        self.obj: dict[str, Any] = obj

    def fail(self, what: str) -> NoReturn:
        place = f"{self.path}: {self.where}: " if self.where else f"{self.path}: "
        raise PlanError(place + what)

    def has(self, key: str) -> bool:
        return key in self.obj

    def get(self, key: str, expected: str) -> Any:
        if key not in self.obj:
            self.fail(f'missing field "{self.prefix}{key}", expected {expected}')
        return self.obj[key]

    def integer(self, key: str) -> int:
        value = self.get(key, "an integer")
        if not _is_number(value) or not math.isfinite(value) or value != int(value):
            self.fail(f'field "{self.prefix}{key}" must be an integer ({json.dumps(value)})')
        return int(value)

    def number(self, key: str, expected: str = "a number") -> float:
        value = self.get(key, expected)
        if not _is_number(value):
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({json.dumps(value)})')
        return float(value)

    def boolean(self, key: str) -> bool:
        value = self.get(key, "true or false")
        if not isinstance(value, bool):
            self.fail(f'field "{self.prefix}{key}" must be true or false ({json.dumps(value)})')
        return value

    def array(self, key: str, expected: str) -> list[Any]:
        value = self.get(key, expected)
        if not isinstance(value, list):
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({_type_name(value)})')
        return value

    def numbers(self, key: str, count: int, expected: str, *, nulls: bool = False) -> list[float]:
        """An array of exactly ``count`` numbers (``null`` -> NaN when ``nulls``)."""
        values = self.array(key, expected)
        if len(values) != count:
            self.fail(f'field "{self.prefix}{key}" must be {expected} ({len(values)} values)')
        return self.to_floats(key, values, expected, nulls=nulls)

    def to_floats(
        self, key: str, values: list[Any], expected: str, *, nulls: bool = False
    ) -> list[float]:
        out: list[float] = []
        for value in values:
            if value is None and nulls:
                out.append(math.nan)
            elif _is_number(value):
                out.append(float(value))
            else:
                self.fail(
                    f'field "{self.prefix}{key}" must be {expected} ({json.dumps(value)} in it)'
                )
        return out


def _plan_from_text(text: str, path: PathLike) -> Mission:
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        msg = (
            f"{path}: not JSON, expected a QGroundControl .plan (JSON) or QGC WPL 110 file "
            f"({err.msg} at line {err.lineno} column {err.colno})"
        )
        raise PlanError(msg) from None
    top = _Json(doc, path, "")
    file_type = top.get("fileType", '"Plan"')
    if file_type != PLAN_FILE_TYPE:
        top.fail(
            f'fileType is not "Plan", expected a QGroundControl plan ({json.dumps(file_type)})'
        )
    version = top.integer("version")
    if version != PLAN_VERSION:
        top.fail(f"plan version not supported, expected {PLAN_VERSION} ({version})")

    mission_json = _Json(top.get("mission", "an object"), path, "", "mission.")
    mission_version = mission_json.integer("version")
    if mission_version != MISSION_VERSION:
        mission_json.fail(
            f"mission version not supported, expected {MISSION_VERSION} ({mission_version})"
        )
    home = mission_json.numbers("plannedHomePosition", 3, "[latitude, longitude, altitude AMSL]")
    cruise = 15.0
    if mission_json.has("cruiseSpeed"):
        cruise = mission_json.number("cruiseSpeed", "a speed in m/s")
        if not (math.isfinite(cruise) and cruise > 0):
            mission_json.fail(f"cruiseSpeed must be > 0 m/s ({cruise})")
    raw_items = mission_json.array("items", "an array of mission items")

    items = [_simple_item(raw, index, path) for index, raw in enumerate(raw_items)]
    items = _resolve_jumps(items, raw_items, path)

    fence: tuple[MissionItem, ...] = ()
    if top.has("geoFence"):
        fence = _read_fence(_Json(top.obj["geoFence"], path, "", "geoFence."), path)
    rally: tuple[MissionItem, ...] = ()
    if top.has("rallyPoints"):
        rally = _read_rally(_Json(top.obj["rallyPoints"], path, "", "rallyPoints."))

    return Mission(
        items=tuple(items),
        planned_home=GeoPoint(lat_deg=home[0], lon_deg=home[1], alt_amsl_m=home[2]),
        cruise_speed_m_s=cruise,
        fence=fence,
        rally=rally,
        source=str(path),
        name=Path(path).stem,
    )


def _simple_item(raw: object, index: int, path: PathLike) -> MissionItem:
    item = _Json(raw, path, f"item {index}")
    kind = item.get("type", '"SimpleItem"')
    if kind == "ComplexItem":
        complex_type = item.obj.get("complexItemType", "unknown")
        item.fail(
            "complex items (survey, corridor scan, structure scan) are not supported, expected "
            f"SimpleItems: convert it to waypoints in QGroundControl ({complex_type})"
        )
    if kind != "SimpleItem":
        item.fail(f'unknown item type, expected "SimpleItem" ({json.dumps(kind)})')
    command = item.integer("command")
    frame = item.integer("frame")
    autocontinue = item.boolean("autoContinue")
    expected = "an array of 7 numbers or nulls"
    raw_params = item.array("params", expected)
    if len(raw_params) == 4 and item.has("coordinate"):
        # QGC's older SimpleItem layout: params 1..4 plus "coordinate": [lat, lon, alt].
        params = item.to_floats("params", raw_params, expected, nulls=True)
        params += item.numbers("coordinate", 3, "[latitude, longitude, altitude]", nulls=True)
    else:
        params = item.numbers("params", 7, expected, nulls=True)
    if item.has("doJumpId"):
        item.integer("doJumpId")
    return MissionItem.from_params(command, frame, params, autocontinue=autocontinue, seq=index)


def _resolve_jumps(
    items: list[MissionItem], raw_items: list[Any], path: PathLike
) -> list[MissionItem]:
    """Turn DO_JUMP targets from doJumpIds into sequence indices (see module docstring)."""
    ids: dict[int, int] = {}
    for index, raw in enumerate(raw_items):
        # A missing doJumpId means "the one QGC would write on save": index + 1.
        jump_id = int(raw.get("doJumpId", index + 1))
        ids.setdefault(jump_id, index)
    out: list[MissionItem] = []
    for index, item in enumerate(items):
        if item.command == MavCmd.DO_JUMP:
            target = item.param1
            if not (math.isfinite(target) and target == int(target) and int(target) in ids):
                known = _describe_ids(sorted(ids))
                msg = (
                    f"{path}: item {index}: DO_JUMP target is not the doJumpId of any item, "
                    f"expected one of {known} ({target})"
                )
                raise PlanError(msg)
            out.append(dataclasses.replace(item, param1=float(ids[int(target)])))
        else:
            out.append(item)
    return out


def _describe_ids(ids: list[int]) -> str:
    if not ids:
        return "none (no items)"
    if ids == list(range(ids[0], ids[-1] + 1)) and len(ids) > 3:
        return f"{ids[0]}..{ids[-1]}"
    shown = ", ".join(str(k) for k in ids[:10])
    return shown + (", ..." if len(ids) > 10 else "")


def _latlon(entry: _Json, key: str, value: object, expected: str, count: int) -> list[float]:
    if not isinstance(value, list) or len(value) < count:
        entry.fail(f'field "{entry.prefix}{key}" must be {expected} ({json.dumps(value)})')
    return entry.to_floats(key, value[:count], expected, nulls=True)


def _read_fence(geo: _Json, path: PathLike) -> tuple[MissionItem, ...]:
    """geoFence polygons, circles and breach return point as MAVLink fence items."""
    out: list[MissionItem] = []
    polygons = geo.array("polygons", "an array of polygons") if geo.has("polygons") else []
    for p, raw in enumerate(polygons):
        polygon = _Json(raw, path, f"geoFence polygon {p}")
        inclusion = polygon.boolean("inclusion")
        vertices = polygon.array("polygon", "an array of [latitude, longitude]")
        command = _POLYGON_CMDS[0] if inclusion else _POLYGON_CMDS[1]
        for vertex in vertices:
            lat, lon = _latlon(polygon, "polygon", vertex, "an array of [latitude, longitude]", 2)
            out.append(
                MissionItem(
                    command=command,
                    frame=MavFrame.GLOBAL,
                    param1=float(len(vertices)),
                    param4=0.0,
                    lat_deg=lat,
                    lon_deg=lon,
                )
            )
    circles = geo.array("circles", "an array of circles") if geo.has("circles") else []
    for c, raw in enumerate(circles):
        circle = _Json(raw, path, f"geoFence circle {c}")
        inclusion = circle.boolean("inclusion")
        shape = _Json(circle.get("circle", "an object"), path, f"geoFence circle {c}", "circle.")
        lat, lon = _latlon(shape, "center", shape.get("center", "[lat, lon]"), "[lat, lon]", 2)
        out.append(
            MissionItem(
                command=_CIRCLE_CMDS[0] if inclusion else _CIRCLE_CMDS[1],
                frame=MavFrame.GLOBAL,
                param1=shape.number("radius", "a radius in metres"),
                param4=0.0,
                lat_deg=lat,
                lon_deg=lon,
            )
        )
    if geo.has("breachReturn"):
        expected = "[latitude, longitude, altitude]"
        lat, lon, alt = _latlon(geo, "breachReturn", geo.obj["breachReturn"], expected, 3)
        out.append(
            MissionItem(
                command=MavCmd.NAV_FENCE_RETURN_POINT,
                frame=MavFrame.GLOBAL_RELATIVE_ALT,
                param4=0.0,
                lat_deg=lat,
                lon_deg=lon,
                alt_m=alt,
            )
        )
    return tuple(out)


def _read_rally(rally: _Json) -> tuple[MissionItem, ...]:
    points = rally.array("points", "an array of [latitude, longitude, altitude]")
    out: list[MissionItem] = []
    for point in points:
        lat, lon, alt = _latlon(
            rally, "points", point, "an array of [latitude, longitude, altitude]", 3
        )
        out.append(
            MissionItem(
                command=MavCmd.NAV_RALLY_POINT,
                frame=MavFrame.GLOBAL_RELATIVE_ALT,
                param4=0.0,
                lat_deg=lat,
                lon_deg=lon,
                alt_m=alt,
            )
        )
    return tuple(out)


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
        if item.command in _POLYGON_CMDS and math.isfinite(count) and int(count) >= 1:
            for v in range(int(count)):
                labels.append(f"geoFence polygon {polygons} vertex {v}")
            polygons += 1
            i += int(count)
        elif item.command in _CIRCLE_CMDS:
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


# ---------------------------------------------------------------------------------------------
# QGC WPL 110


def _wpl_from_text(text: str, path: PathLike) -> tuple[Mission, list[str]]:
    """Parse WPL text; also return ``"item i (line n)"`` labels for messages."""
    lines = text.splitlines()
    header = lines[0].strip() if lines else ""
    if header != WPL_HEADER:
        msg = f'{path}: line 1: expected the header "{WPL_HEADER}" ({header!r})'
        raise PlanError(msg)
    rows: list[tuple[int, list[str]]] = [
        (number, line.split()) for number, line in enumerate(lines[1:], start=2) if line.strip()
    ]
    if not rows:
        msg = f"{path}: no home line after the header, expected seq 0 = home position"
        raise PlanError(msg)
    parsed: list[tuple[int, tuple[int, int, int, int], list[float], bool]] = []
    for expected_seq, (number, cols) in enumerate(rows):
        where = f"{path}: line {number}"
        if len(cols) != len(WPL_COLUMNS):
            msg = (
                f"{where}: expected {len(WPL_COLUMNS)} tab-separated columns "
                f"({' '.join(WPL_COLUMNS)}), found {len(cols)} ({' '.join(cols)[:60]!r})"
            )
            raise PlanError(msg)
        ints: list[int] = []
        for col in (0, 1, 2, 3):
            try:
                ints.append(int(cols[col]))
            except ValueError:
                msg = f"{where}: column {WPL_COLUMNS[col]} must be an integer ({cols[col]!r})"
                raise PlanError(msg) from None
        floats: list[float] = []
        for col in range(4, 11):
            try:
                floats.append(float(cols[col]))
            except ValueError:
                msg = f"{where}: column {WPL_COLUMNS[col]} must be a number ({cols[col]!r})"
                raise PlanError(msg) from None
        if cols[11] not in ("0", "1"):
            msg = f"{where}: column autocontinue must be 0 or 1 ({cols[11]!r})"
            raise PlanError(msg)
        if ints[0] != expected_seq:
            msg = f"{where}: sequence number out of order, expected {expected_seq} ({ints[0]})"
            raise PlanError(msg)
        parsed.append((number, (ints[0], ints[1], ints[2], ints[3]), floats, cols[11] == "1"))

    _, _, home, _ = parsed[0]
    items: list[MissionItem] = []
    labels: list[str] = []
    count = len(parsed) - 1
    for index, (number, (_seq, _current, frame, command), p, autocontinue) in enumerate(parsed[1:]):
        param1 = p[0]
        if command == MavCmd.DO_JUMP:
            # WPL counts home as seq 0: target seq s is mission index s - 1.
            if not (math.isfinite(param1) and param1 == int(param1) and 1 <= param1 <= count):
                msg = (
                    f"{path}: item {index} (line {number}): DO_JUMP target is not an item "
                    f"sequence number, expected 1..{count} ({param1})"
                )
                raise PlanError(msg)
            param1 -= 1.0
        items.append(
            MissionItem.from_params(
                command, frame, (param1, *p[1:7]), autocontinue=autocontinue, seq=index
            )
        )
        labels.append(f"item {index} (line {number})")
    mission = Mission(
        items=tuple(items),
        planned_home=GeoPoint(lat_deg=home[4], lon_deg=home[5], alt_amsl_m=home[6]),
        source=str(path),
        name=Path(path).stem,
    )
    return mission, labels


# ---------------------------------------------------------------------------------------------
# Writing


def _num(value: float, where: str) -> float | int | None:
    """JSON number for a param: NaN -> null, whole numbers as integers (as QGC writes them)."""
    if math.isnan(value):
        return None
    if math.isinf(value):
        msg = f"{where}: cannot write an infinite value to a plan ({value})"
        raise PlanError(msg)
    if value == int(value) and abs(value) < 2**53:
        return int(value)
    return value


def _plan_document(mission: Mission, where: str) -> dict[str, Any]:
    home = mission.planned_home
    if home is None:
        msg = f"{where}: cannot write a plan without a planned home position"
        raise PlanError(msg)
    items: list[dict[str, Any]] = []
    for index, item in enumerate(mission.items):
        place = f"{where}: item {index}"
        param1 = item.param1
        if item.command == MavCmd.DO_JUMP and math.isfinite(param1):
            param1 += 1.0  # sequence index -> doJumpId
        params = (
            param1,
            item.param2,
            item.param3,
            item.param4,
            item.lat_deg,
            item.lon_deg,
            item.alt_m,
        )
        items.append(
            {
                "autoContinue": bool(item.autocontinue),
                "command": int(item.command),
                "doJumpId": index + 1,
                "frame": int(item.frame),
                "params": [_num(p, place) for p in params],
                "type": "SimpleItem",
            }
        )
    return {
        "fileType": PLAN_FILE_TYPE,
        "geoFence": _fence_document(mission.fence, where),
        "groundStation": GROUND_STATION,
        "mission": {
            "cruiseSpeed": _num(mission.cruise_speed_m_s, f"{where}: cruiseSpeed"),
            "firmwareType": FIRMWARE_PX4,
            "hoverSpeed": _num(HOVER_SPEED_M_S, where),
            "items": items,
            "plannedHomePosition": [
                _num(home.lat_deg, f"{where}: plannedHomePosition"),
                _num(home.lon_deg, f"{where}: plannedHomePosition"),
                _num(home.alt_amsl_m, f"{where}: plannedHomePosition"),
            ],
            "vehicleType": VEHICLE_FIXED_WING,
            "version": MISSION_VERSION,
        },
        "rallyPoints": {
            "points": [
                [
                    _num(p.lat_deg, f"{where}: rally point {i}"),
                    _num(p.lon_deg, f"{where}: rally point {i}"),
                    _num(p.alt_m, f"{where}: rally point {i}"),
                ]
                for i, p in enumerate(mission.rally)
            ],
            "version": RALLY_VERSION,
        },
        "version": PLAN_VERSION,
    }


def _fence_document(fence: Sequence[MissionItem], where: str) -> dict[str, Any]:
    polygons: list[dict[str, Any]] = []
    circles: list[dict[str, Any]] = []
    doc: dict[str, Any] = {"version": FENCE_VERSION}
    i = 0
    while i < len(fence):
        item = fence[i]
        place = f"{where}: fence item {i}"
        if item.command in _POLYGON_CMDS:
            count = int(item.param1) if math.isfinite(item.param1) else 0
            run = fence[i : i + count]
            if count < 1 or len(run) != count or any(v.command != item.command for v in run):
                msg = f"{place}: polygon vertex count does not match its vertices ({item.param1})"
                raise PlanError(msg)
            polygons.append(
                {
                    "inclusion": item.command == MavCmd.NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                    "polygon": [[_num(v.lat_deg, place), _num(v.lon_deg, place)] for v in run],
                    "version": 1,
                }
            )
            i += count
            continue
        if item.command in _CIRCLE_CMDS:
            circles.append(
                {
                    "circle": {
                        "center": [_num(item.lat_deg, place), _num(item.lon_deg, place)],
                        "radius": _num(item.param1, place),
                    },
                    "inclusion": item.command == MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
                    "version": 1,
                }
            )
        elif item.command == MavCmd.NAV_FENCE_RETURN_POINT:
            doc["breachReturn"] = [
                _num(item.lat_deg, place),
                _num(item.lon_deg, place),
                _num(item.alt_m, place),
            ]
        else:
            msg = f"{place}: not a fence command ({item.command})"
            raise PlanError(msg)
        i += 1
    doc["circles"] = circles
    doc["polygons"] = polygons
    return doc
