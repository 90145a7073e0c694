"""QGroundControl ``.plan`` JSON: reading a plan into a Mission and writing one back.

The public entry points are in :mod:`air_sitl.mission.plan_file`; the conventions (DO_JUMP
targets as doJumpIds, fence and rally items) are described there.
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from air_sitl.errors import PlanError
from air_sitl.mission.items import (
    FENCE_CIRCLE_COMMANDS,
    FENCE_POLYGON_COMMANDS,
    MavCmd,
    MavFrame,
    Mission,
    MissionItem,
)
from air_sitl.mission.reading import JsonObject, PathLike
from air_sitl.state import GeoPoint

PLAN_FILE_TYPE = "Plan"
PLAN_VERSION = 1
MISSION_VERSION = 2
FENCE_VERSION = 2
RALLY_VERSION = 2
FIRMWARE_PX4 = 12  # MAV_AUTOPILOT_PX4
VEHICLE_FIXED_WING = 1  # MAV_TYPE_FIXED_WING
HOVER_SPEED_M_S = 5.0  # QGC's default; unused by a fixed-wing, written because QGC expects it
GROUND_STATION = "air-sitl"


# ---------------------------------------------------------------------------------------------
# Reading


# MAV_TYPE names for the vehicleType warning (a plan made for another vehicle).
_VEHICLE_TYPES = {0: "GENERIC", 2: "QUADROTOR", 3: "COAXIAL", 4: "HELICOPTER", 10: "GROUND_ROVER",
                  11: "SURFACE_BOAT", 12: "SUBMARINE", 13: "HEXAROTOR", 14: "OCTOROTOR",
                  15: "TRICOPTER", 19: "VTOL_TAILSITTER_DUOROTOR", 20: "VTOL_TAILSITTER_QUADROTOR",
                  21: "VTOL_TILTROTOR", 22: "VTOL_FIXEDROTOR", 23: "VTOL_TAILSITTER",
                  29: "DODECAROTOR"}  # fmt: skip
# QGC complex items and where their generated mission items are in the file.
_COMPLEX_NAMES = {
    "survey": "survey",
    "CorridorScan": "corridor scan",
    "StructureScan": "structure scan",
    "fwLandingPattern": "fixed-wing landing pattern",
    "vtolLandingPattern": "VTOL landing pattern",
}


def plan_from_text(text: str, path: PathLike) -> Mission:
    """Parse the text of a ``.plan`` file (structure only; DO_JUMP targets become indices)."""
    return plan_and_labels(text, path)[0]


def plan_and_labels(text: str, path: PathLike) -> tuple[Mission, list[str]]:
    """Parse a ``.plan``; also return a label per mission item for messages (``item 3``, or
    ``item 2 (survey, generated item 5)`` for the items a QGC complex item generated)."""
    try:
        doc = json.loads(text)
    except json.JSONDecodeError as err:
        msg = (
            f"{path}: not JSON, expected a QGroundControl .plan (JSON) or QGC WPL 110 file "
            f"({err.msg} at line {err.lineno} column {err.colno})"
        )
        raise PlanError(msg) from None
    top = JsonObject(doc, path, "")
    file_type = top.get("fileType", '"Plan"')
    if file_type != PLAN_FILE_TYPE:
        top.fail(
            f'fileType is not "Plan", expected a QGroundControl plan ({json.dumps(file_type)})'
        )
    version = top.integer("version")
    if version != PLAN_VERSION:
        top.fail(f"plan version not supported, expected {PLAN_VERSION} ({version})")

    mission_json = JsonObject(top.get("mission", "an object"), path, "", "mission.")
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
    plan_items = mission_json.array("items", "an array of mission items")
    notes: list[str] = []
    if mission_json.has("vehicleType"):
        vehicle = mission_json.integer("vehicleType")
        if vehicle != VEHICLE_FIXED_WING:
            name = _VEHICLE_TYPES.get(vehicle, str(vehicle))
            notes.append(
                f"mission.vehicleType is {name} ({vehicle}), not FIXED_WING (1): the plan was made "
                "for another vehicle; it is flown by the fixed-wing aircraft"
            )

    raw_items: list[Any] = []
    labels: list[str] = []
    for index, raw in enumerate(plan_items):
        for where, generated in _expand(raw, index, path):
            labels.append(where)
            raw_items.append(generated)
    items = [
        _simple_item(raw, seq, path, where)
        for seq, (raw, where) in enumerate(zip(raw_items, labels, strict=True))
    ]
    items = _resolve_jumps(items, raw_items, path)

    fence: tuple[MissionItem, ...] = ()
    if top.has("geoFence"):
        fence = _read_fence(JsonObject(top.obj["geoFence"], path, "", "geoFence."), path)
    rally: tuple[MissionItem, ...] = ()
    if top.has("rallyPoints"):
        rally = _read_rally(JsonObject(top.obj["rallyPoints"], path, "", "rallyPoints."))

    mission = Mission(
        items=tuple(items),
        planned_home=GeoPoint(lat_deg=home[0], lon_deg=home[1], alt_amsl_m=home[2]),
        cruise_speed_m_s=cruise,
        fence=fence,
        rally=rally,
        source=str(path),
        name=Path(path).stem,
        notes=tuple(notes),
    )
    return mission, labels


def _expand(raw: object, index: int, path: PathLike) -> list[tuple[str, Any]]:
    """(label, SimpleItem JSON) of one plan item: itself, or what a complex item generated.

    QGroundControl writes the mission items a survey or corridor scan generated under
    ``TransectStyleComplexItem.Items`` and a structure scan's under ``Items``; those are flown
    (their camera trigger items feed the capture window).
    """
    item = JsonObject(raw, path, f"item {index}")
    if item.obj.get("type") != "ComplexItem":
        return [(f"item {index}", raw)]
    complex_type = item.obj.get("complexItemType", "unknown")
    name = _COMPLEX_NAMES.get(str(complex_type), str(complex_type))
    generated: object = None
    transect = item.obj.get("TransectStyleComplexItem")
    if isinstance(transect, dict):
        generated = transect.get("Items")
    if generated is None:
        generated = item.obj.get("Items")
    if not isinstance(generated, list) or not generated:
        item.fail(
            f"QGroundControl {name} without the mission items it generates, expected "
            "TransectStyleComplexItem.Items or Items: save the plan again with QGroundControl, "
            f"or convert the item to waypoints ({complex_type})"
        )
    out: list[tuple[str, Any]] = []
    for k, sub in enumerate(generated):
        where = f"item {index} ({name}, generated item {k})"
        if isinstance(sub, dict) and sub.get("type") == "ComplexItem":
            JsonObject(sub, path, where).fail("nested complex item, expected SimpleItems")
        out.append((where, sub))
    return out


def _simple_item(raw: object, index: int, path: PathLike, where: str = "") -> MissionItem:
    item = JsonObject(raw, path, where or f"item {index}")
    kind = item.get("type", '"SimpleItem"')
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


def _latlon(entry: JsonObject, key: str, value: object, expected: str, count: int) -> list[float]:
    if not isinstance(value, list) or len(value) < count:
        entry.fail(f'field "{entry.prefix}{key}" must be {expected} ({json.dumps(value)})')
    return entry.to_floats(key, value[:count], expected, nulls=True)


def _read_fence(geo: JsonObject, path: PathLike) -> tuple[MissionItem, ...]:
    """geoFence polygons, circles and breach return point as MAVLink fence items."""
    out: list[MissionItem] = []
    polygons = geo.array("polygons", "an array of polygons") if geo.has("polygons") else []
    for p, raw in enumerate(polygons):
        polygon = JsonObject(raw, path, f"geoFence polygon {p}")
        inclusion = polygon.boolean("inclusion")
        vertices = polygon.array("polygon", "an array of [latitude, longitude]")
        command = FENCE_POLYGON_COMMANDS[0] if inclusion else FENCE_POLYGON_COMMANDS[1]
        for vertex in vertices:
            lat, lon = _latlon(polygon, "polygon", vertex, "an array of [latitude, longitude]", 2)
            out.append(_point_item(command, MavFrame.GLOBAL, lat, lon, param1=float(len(vertices))))
    circles = geo.array("circles", "an array of circles") if geo.has("circles") else []
    for c, raw in enumerate(circles):
        circle = JsonObject(raw, path, f"geoFence circle {c}")
        inclusion = circle.boolean("inclusion")
        shape = JsonObject(
            circle.get("circle", "an object"), path, f"geoFence circle {c}", "circle."
        )
        lat, lon = _latlon(shape, "center", shape.get("center", "[lat, lon]"), "[lat, lon]", 2)
        command = FENCE_CIRCLE_COMMANDS[0] if inclusion else FENCE_CIRCLE_COMMANDS[1]
        radius = shape.number("radius", "a radius in metres")
        out.append(_point_item(command, MavFrame.GLOBAL, lat, lon, param1=radius))
    if geo.has("breachReturn"):
        expected = "[latitude, longitude, altitude]"
        lat, lon, alt = _latlon(geo, "breachReturn", geo.obj["breachReturn"], expected, 3)
        command = MavCmd.NAV_FENCE_RETURN_POINT
        out.append(_point_item(command, MavFrame.GLOBAL_RELATIVE_ALT, lat, lon, alt=alt))
    return tuple(out)


def _read_rally(rally: JsonObject) -> tuple[MissionItem, ...]:
    points = rally.array("points", "an array of [latitude, longitude, altitude]")
    out: list[MissionItem] = []
    for point in points:
        lat, lon, alt = _latlon(
            rally, "points", point, "an array of [latitude, longitude, altitude]", 3
        )
        command = MavCmd.NAV_RALLY_POINT
        out.append(_point_item(command, MavFrame.GLOBAL_RELATIVE_ALT, lat, lon, alt=alt))
    return tuple(out)


def _point_item(
    command: int, frame: int, lat: float, lon: float, *, param1: float = 0.0, alt: float = 0.0
) -> MissionItem:
    """A fence or rally item at a point (``param4`` 0, as QGC uploads them)."""
    return MissionItem(
        command=command, frame=frame, param1=param1, param4=0.0, lat_deg=lat, lon_deg=lon, alt_m=alt
    )


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


def plan_document(mission: Mission, where: str) -> dict[str, Any]:
    """The ``.plan`` JSON object of a mission; ``where`` names it in error messages."""
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
        params = (param1, *item.params[1:])
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
        if item.command in FENCE_POLYGON_COMMANDS:
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
        if item.command in FENCE_CIRCLE_COMMANDS:
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
