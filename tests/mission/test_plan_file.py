"""QGC .plan and WPL reading, writing, round trips and one-line user errors."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from air_sitl.errors import PlanError
from air_sitl.mission.items import MavCmd, MavFrame, Mission, MissionItem
from air_sitl.mission.plan_file import (
    load_mission,
    plan_text,
    read_plan,
    read_wpl,
    validate_mission,
    write_plan,
)
from air_sitl.state import GeoPoint

from .conftest import PlanWriter


def item_key(item: MissionItem) -> tuple[object, ...]:
    """Comparable form of an item: NaN -> "nan" (NaN != NaN would defeat equality)."""
    values = (item.command, item.frame, *item.params, item.autocontinue, item.do_jump_id)
    return tuple("nan" if isinstance(v, float) and math.isnan(v) else v for v in values)


def mission_key(m: Mission) -> tuple[object, ...]:
    return (
        tuple(item_key(i) for i in m.items),
        tuple(item_key(i) for i in m.fence),
        tuple(item_key(i) for i in m.rally),
        m.planned_home,
        m.cruise_speed_m_s,
    )


# --- reading ------------------------------------------------------------------------------------


def test_read_plan_maps_items_fence_rally(base_plan: dict[str, Any], write_doc: PlanWriter) -> None:
    path = write_doc(base_plan, "FX-100.plan")
    m = read_plan(path)
    assert m.name == "FX-100"
    assert m.source == str(path)
    assert m.planned_home == GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
    assert m.cruise_speed_m_s == 15.0
    assert [i.command for i in m.items] == [22, 178, 16, 16, 177, 2000, 18, 2001, 20]
    takeoff = m.items[0]
    assert (takeoff.frame, takeoff.param1, takeoff.alt_m) == (MavFrame.GLOBAL_RELATIVE_ALT, 15, 100)
    assert math.isnan(takeoff.param4)  # null -> NaN
    assert m.items[3].alt_m == 100.5
    assert [i.do_jump_id for i in m.items] == list(range(1, 10))
    # DO_JUMP: doJumpId 3 in the file is sequence index 2 in the Mission.
    assert m.items[4].param1 == 2.0
    assert m.items[4].param2 == 1.0
    # Fence: polygon vertices carry the vertex count in param1, then the circle, then return.
    assert [f.command for f in m.fence] == [5002, 5002, 5002, 5003, 5000]
    assert [f.param1 for f in m.fence[:3]] == [3.0, 3.0, 3.0]
    assert (m.fence[1].lat_deg, m.fence[1].lon_deg) == (47.41, 8.55)
    assert m.fence[3].param1 == 1500.0
    assert m.fence[4].alt_m == 120.0
    assert [(r.command, r.alt_m) for r in m.rally] == [(5100, 80.0), (5100, 90.0)]


def test_do_jump_ids_need_not_be_sequence_numbers(
    base_plan: dict[str, Any], write_doc: PlanWriter
) -> None:
    items = base_plan["mission"]["items"]
    for n, item in enumerate(items):
        item["doJumpId"] = 100 + 10 * n  # unusual ids: targets resolve by id, not position
    items[4]["params"][0] = 120  # -> item 2
    m = read_plan(write_doc(base_plan))
    assert m.items[4].param1 == 2.0
    assert [i.do_jump_id for i in m.items] == list(range(1, 10))


def test_missing_do_jump_id_counts_as_sequence_number(
    base_plan: dict[str, Any], write_doc: PlanWriter
) -> None:
    for item in base_plan["mission"]["items"]:
        del item["doJumpId"]
    m = read_plan(write_doc(base_plan))
    assert m.items[4].param1 == 2.0


def test_legacy_coordinate_layout(base_plan: dict[str, Any], write_doc: PlanWriter) -> None:
    item = base_plan["mission"]["items"][2]
    item["coordinate"] = item["params"][4:]
    item["params"] = item["params"][:4]
    m = read_plan(write_doc(base_plan))
    assert (m.items[2].lat_deg, m.items[2].lon_deg, m.items[2].alt_m) == (47.4005, 8.5460, 100)


def test_geofence_and_rally_are_optional(base_plan: dict[str, Any], write_doc: PlanWriter) -> None:
    del base_plan["geoFence"]
    del base_plan["rallyPoints"]
    m = load_mission(write_doc(base_plan))
    assert m.fence == ()
    assert m.rally == ()


# --- writing and round trips -----------------------------------------------------------------


def test_round_trip_read_write_read(
    base_plan: dict[str, Any], write_doc: PlanWriter, tmp_path: Path
) -> None:
    first = read_plan(write_doc(base_plan))
    out = tmp_path / "copy.plan"
    write_plan(first, out)
    second = read_plan(out)
    assert mission_key(second) == mission_key(first)
    # the file written carries doJumpIds back: DO_JUMP param1 is the target's doJumpId again
    doc = json.loads(out.read_text())
    assert doc["mission"]["items"][4]["params"][0] == 3
    assert [i["doJumpId"] for i in doc["mission"]["items"]] == list(range(1, 10))
    assert doc["geoFence"]["polygons"] == base_plan["geoFence"]["polygons"]
    assert doc["geoFence"]["circles"] == base_plan["geoFence"]["circles"]
    assert doc["geoFence"]["breachReturn"] == base_plan["geoFence"]["breachReturn"]
    assert doc["rallyPoints"] == base_plan["rallyPoints"]
    assert doc["mission"]["items"][0]["params"][3] is None  # NaN -> null


def test_write_is_deterministic(
    base_plan: dict[str, Any], write_doc: PlanWriter, tmp_path: Path
) -> None:
    m = read_plan(write_doc(base_plan))
    write_plan(m, tmp_path / "a.plan")
    write_plan(read_plan(tmp_path / "a.plan"), tmp_path / "b.plan")
    a = (tmp_path / "a.plan").read_bytes()
    assert a == (tmp_path / "b.plan").read_bytes()
    assert a == plan_text(m).encode()
    assert a.endswith(b"}\n")
    assert not list(tmp_path.glob("*.tmp"))  # atomic write leaves no temporary file


def test_write_refuses_infinite_values(tmp_path: Path) -> None:
    m = Mission(
        items=(MissionItem(command=MavCmd.NAV_WAYPOINT, param1=math.inf, lat_deg=1, lon_deg=2),),
        planned_home=GeoPoint(lat_deg=1, lon_deg=2, alt_amsl_m=3),
    )
    with pytest.raises(PlanError, match=r"x\.plan: item 0: .*\(inf\)"):
        write_plan(m, tmp_path / "x.plan")


def test_write_refuses_a_mission_without_home(tmp_path: Path) -> None:
    m = Mission(items=(MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=1, lon_deg=2),))
    with pytest.raises(PlanError, match="planned home"):
        write_plan(m, tmp_path / "x.plan")


# Valid missions for the property test: the numbers JSON carries exactly (doubles), with NaN
# where QGC writes null.
_finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
_param = st.one_of(_finite, st.just(math.nan))
_lat = st.floats(min_value=-90, max_value=90)
_lon = st.floats(min_value=-180, max_value=180)
_global_frames = st.sampled_from([0, 3, 5, 6])


@st.composite
def _nav_item(draw: st.DrawFn) -> MissionItem:
    command = draw(
        st.sampled_from(
            [
                MavCmd.NAV_WAYPOINT,
                MavCmd.NAV_LOITER_UNLIM,
                MavCmd.NAV_LAND,
                MavCmd.NAV_LOITER_TO_ALT,
            ]
        )
    )
    return MissionItem(
        command=command,
        frame=draw(_global_frames),
        param1=draw(_param),
        param2=draw(_param),
        param3=draw(_param),
        param4=draw(_param),
        lat_deg=draw(_lat),
        lon_deg=draw(_lon),
        alt_m=draw(_finite),
        autocontinue=draw(st.booleans()),
    )


@st.composite
def _missions(draw: st.DrawFn) -> Mission:
    items = draw(st.lists(_nav_item(), min_size=1, max_size=8))
    for _ in range(draw(st.integers(0, 2))):  # DO_JUMPs to existing items
        target = draw(st.integers(0, len(items) - 1))
        jump = MissionItem(
            command=MavCmd.DO_JUMP,
            frame=MavFrame.MISSION,
            param1=float(target),
            param2=float(draw(st.integers(0, 5))),
            param3=draw(_param),
            param4=draw(_param),
            lat_deg=draw(_param),
            lon_deg=draw(_param),
            alt_m=draw(_param),
        )
        items.insert(draw(st.integers(target + 1, len(items))), jump)
    items = [MissionItem(**{**_fields(it), "do_jump_id": n + 1}) for n, it in enumerate(items)]
    fence: list[MissionItem] = []
    for _ in range(draw(st.integers(0, 2))):
        n = draw(st.integers(3, 6))
        command = draw(st.sampled_from([5001, 5002]))
        fence += [
            MissionItem(
                command=command,
                frame=MavFrame.GLOBAL,
                param1=float(n),
                param4=0.0,
                lat_deg=draw(_lat),
                lon_deg=draw(_lon),
            )
            for _ in range(n)
        ]
    for _ in range(draw(st.integers(0, 2))):
        fence.append(
            MissionItem(
                command=draw(st.sampled_from([5003, 5004])),
                frame=MavFrame.GLOBAL,
                param1=draw(st.floats(min_value=1, max_value=1e5)),
                param4=0.0,
                lat_deg=draw(_lat),
                lon_deg=draw(_lon),
            )
        )
    rally = [
        MissionItem(
            command=5100,
            frame=MavFrame.GLOBAL_RELATIVE_ALT,
            param4=0.0,
            lat_deg=draw(_lat),
            lon_deg=draw(_lon),
            alt_m=draw(_finite),
        )
        for _ in range(draw(st.integers(0, 3)))
    ]
    return Mission(
        items=tuple(items),
        planned_home=GeoPoint(lat_deg=draw(_lat), lon_deg=draw(_lon), alt_amsl_m=draw(_finite)),
        cruise_speed_m_s=draw(st.floats(min_value=0.1, max_value=100)),
        fence=tuple(fence),
        rally=tuple(rally),
    )


def _fields(item: MissionItem) -> dict[str, Any]:
    return {name: getattr(item, name) for name in MissionItem.__dataclass_fields__}


@settings(max_examples=150, deadline=None)
@given(mission=_missions())
def test_property_write_read_round_trip(mission: Mission, tmp_path_factory: Any) -> None:
    path = tmp_path_factory.mktemp("prop") / "m.plan"
    write_plan(mission, path)
    back = read_plan(path)
    assert mission_key(back) == mission_key(mission)
    validate_mission(back)  # valid in, valid out
    write_plan(back, path.with_name("again.plan"))
    assert path.with_name("again.plan").read_bytes() == path.read_bytes()


# --- QGC WPL 110 ----------------------------------------------------------------------------

WPL = (
    "QGC WPL 110\n"
    "0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.000000\t1\n"
    "1\t0\t3\t22\t15\t0\t0\t0\t47.398500\t8.545600\t100.000000\t1\n"
    "2\t0\t3\t16\t0\t0\t0\t0\t47.400500\t8.546000\t100.000000\t1\n"
    "3\t0\t3\t16\t0\t0\t0\t0\t47.400500\t8.550000\t110.000000\t1\n"
    "4\t0\t2\t177\t2\t3\t0\t0\t0\t0\t0\t1\n"
    "\n"
    "5\t0\t3\t20\t0\t0\t0\t0\t0\t0\t0\t0\n"
)


def test_read_wpl(write_doc: PlanWriter) -> None:
    path = write_doc(WPL, "route.waypoints")
    m = read_wpl(path)
    assert m.name == "route"
    assert m.planned_home == GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
    assert [i.command for i in m.items] == [22, 16, 16, 177, 20]
    assert (m.items[2].lat_deg, m.items[2].lon_deg, m.items[2].alt_m) == (47.4005, 8.55, 110.0)
    assert m.items[3].param1 == 1.0  # WPL seq 2 (home is seq 0) -> index 1
    assert m.items[3].param2 == 3.0
    assert m.items[4].autocontinue is False
    assert load_mission(path).items == m.items  # picked by content, whatever the suffix


def test_wpl_to_plan_round_trip(write_doc: PlanWriter, tmp_path: Path) -> None:
    m = read_wpl(write_doc(WPL, "route.txt"))
    write_plan(m, tmp_path / "route.plan")
    assert mission_key(read_plan(tmp_path / "route.plan")) == mission_key(m)


# --- user errors: one line naming the file, the item and the value ---------------------------

Mutation = Callable[[dict[str, Any]], object]


def _set(path: tuple[Any, ...], value: object) -> Mutation:
    def mutate(doc: dict[str, Any]) -> object:
        target: Any = doc
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
        return doc

    return mutate


def _delete(path: tuple[Any, ...]) -> Mutation:
    def mutate(doc: dict[str, Any]) -> object:
        target: Any = doc
        for key in path[:-1]:
            target = target[key]
        del target[path[-1]]
        return doc

    return mutate


def _only_do_items(doc: dict[str, Any]) -> object:
    items = doc["mission"]["items"]
    doc["mission"]["items"] = [items[1], items[5], items[7]]
    return doc


ITEMS = ("mission", "items")
ERROR_CASES: list[tuple[str, Mutation | str, list[str]]] = [
    ("not-json", "{ this is not json", ["not JSON", "line 1"]),
    ("top-level-array", "[1, 2]", ["expected a JSON object", "(array)"]),
    ("wrong-filetype", _set(("fileType",), "GeoFence"), ['fileType is not "Plan"', '"GeoFence"']),
    ("missing-filetype", _delete(("fileType",)), ['missing field "fileType"']),
    ("plan-version", _set(("version",), 7), ["plan version", "(7)"]),
    ("missing-mission", _delete(("mission",)), ['missing field "mission"']),
    ("missing-items", _delete(("mission", "items")), ['missing field "mission.items"']),
    (
        "missing-home",
        _delete(("mission", "plannedHomePosition")),
        ['missing field "mission.plannedHomePosition"', "latitude"],
    ),
    ("missing-command", _delete((*ITEMS, 2, "command")), ["item 2: ", 'missing field "command"']),
    ("missing-params", _delete((*ITEMS, 3, "params")), ["item 3: ", 'missing field "params"']),
    ("short-params", _set((*ITEMS, 3, "params"), [0, 0, 0]), ["item 3: ", "(3 values)"]),
    ("string-command", _set((*ITEMS, 2, "command"), "16"), ["item 2: ", '("16")']),
    (
        "unknown-command",
        _set((*ITEMS, 2, "command"), 9999),
        ["item 2: ", "unknown command", "(9999)"],
    ),
    (
        "unsupported-command",
        _set((*ITEMS, 1, "command"), 179),
        ["item 1: ", "DO_SET_HOME is not supported", "(179)"],
    ),
    ("latitude", _set((*ITEMS, 2, "params", 4), 91.5), ["item 2: ", "latitude", "(91.5)"]),
    ("longitude", _set((*ITEMS, 3, "params", 5), -181), ["item 3: ", "longitude", "(-181.0)"]),
    ("nan-altitude", _set((*ITEMS, 6, "params", 6), None), ["item 6: ", "altitude", "(nan)"]),
    (
        "jump-target-missing",
        _set((*ITEMS, 4, "params", 0), 42),
        ["item 4: ", "DO_JUMP target", "doJumpId", "(42.0)"],
    ),
    ("jump-to-self", _set((*ITEMS, 4, "params", 0), 5), ["item 4: ", "jump itself", "(4)"]),
    (
        "terrain-frame",
        _set((*ITEMS, 3, "frame"), 10),
        ["item 3: ", "terrain", "no terrain model", "(GLOBAL_TERRAIN_ALT)"],
    ),
    (
        "terrain-frame-int",
        _set((*ITEMS, 2, "frame"), 11),
        ["item 2: ", "terrain", "(GLOBAL_TERRAIN_ALT_INT)"],
    ),
    ("local-frame", _set((*ITEMS, 2, "frame"), 1), ["item 2: ", "frame", "(1)"]),
    ("empty-mission", _set(ITEMS, []), ["no navigation item", "(0 items)"]),
    ("only-do-items", _only_do_items, ["no navigation item", "(3 items)"]),
    (
        "complex-item",
        _set((*ITEMS, 3), {"type": "ComplexItem", "complexItemType": "survey", "version": 5}),
        ["item 3: ", "survey without the mission items it generates", "(survey)"],
    ),
    (
        "corridor-scan",
        _set((*ITEMS, 0), {"type": "ComplexItem", "complexItemType": "CorridorScan"}),
        ["item 0: ", "(CorridorScan)"],
    ),
    ("item-type", _set((*ITEMS, 1, "type"), "Thing"), ["item 1: ", '("Thing")']),
    ("negative-speed", _set((*ITEMS, 1, "params", 1), -3), ["item 1: ", "speed", "(-3.0)"]),
    ("takeoff-below-home", _set((*ITEMS, 0, "params", 6), 0), ["item 0: ", "takeoff", "(0.0)"]),
    ("capture-interval", _set((*ITEMS, 5, "params", 1), -1), ["item 5: ", "interval", "(-1.0)"]),
    ("loiter-turns", _set((*ITEMS, 6, "params", 0), 0), ["item 6: ", "turns", "(0.0)"]),
    ("home-latitude", _set(("mission", "plannedHomePosition", 0), 123), ["home", "(123.0)"]),
    ("cruise-speed", _set(("mission", "cruiseSpeed"), 0), ["cruiseSpeed", "(0.0)"]),
    (
        "fence-vertex-latitude",
        _set(("geoFence", "polygons", 0, "polygon", 1, 0), -95),
        ["geoFence polygon 0 vertex 1: ", "latitude", "(-95.0)"],
    ),
    (
        "fence-two-vertices",
        _set(("geoFence", "polygons", 0, "polygon"), [[47.4, 8.5], [47.5, 8.5]]),
        ["geoFence polygon 0 vertex 0: ", "vertex count", "(2.0)"],
    ),
    (
        "fence-circle-radius",
        _set(("geoFence", "circles", 0, "circle", "radius"), 0),
        ["geoFence circle 0: ", "radius", "(0.0)"],
    ),
    (
        "fence-missing-inclusion",
        _delete(("geoFence", "polygons", 0, "inclusion")),
        ["geoFence polygon 0: ", 'missing field "inclusion"'],
    ),
    (
        "rally-longitude",
        _set(("rallyPoints", "points", 1, 1), 200),
        ["rally point 1: ", "longitude", "(200.0)"],
    ),
]


def _refused_in_one_line(path: Path, expected: list[str]) -> None:
    """load_mission refuses ``path`` with one line starting with the path, saying each of
    ``expected``."""
    with pytest.raises(PlanError) as info:
        load_mission(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: ")
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize(
    ("change", "expected"), [c[1:] for c in ERROR_CASES], ids=[c[0] for c in ERROR_CASES]
)
def test_user_errors_are_one_line(
    base_plan: dict[str, Any],
    write_doc: PlanWriter,
    change: Mutation | str,
    expected: list[str],
) -> None:
    doc = change if isinstance(change, str) else change(base_plan)
    path = write_doc(doc, "bad.plan")
    _refused_in_one_line(path, expected)


def test_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.plan"
    with pytest.raises(PlanError, match=r"nowhere\.plan: file not found$"):
        load_mission(path)


def test_folder_instead_of_file(tmp_path: Path) -> None:
    with pytest.raises(PlanError, match="is a folder"):
        load_mission(tmp_path)


def test_binary_file(tmp_path: Path) -> None:
    path = tmp_path / "photo.plan"
    path.write_bytes(b"\xff\xd8\xff\xe0 not text")
    with pytest.raises(PlanError, match=r"photo\.plan: not a text file"):
        load_mission(path)


def _row(columns: str) -> str:
    return "\t".join(columns.split()) + "\n"


WPL_HOME = "QGC WPL 110\n" + _row("0 1 0 16 0 0 0 0 47.3 8.5 488 1")


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("QGC WPL 110\n0\t1\t0\t16\t0\t0\n", ["line 2: ", "12 tab-separated columns", "found 6"]),
        (
            WPL_HOME + _row("1 0 3 16 0 0 0 0 abc 8.5 50 1"),
            ["line 3: ", "x/latitude", "('abc')"],
        ),
        (
            WPL_HOME + _row("2 0 3 16 0 0 0 0 47.3 8.5 50 1"),
            ["line 3: ", "sequence", "(2)"],
        ),
        (
            WPL_HOME + _row("1 0 3 16 0 0 0 0 47.3 8.5 50 yes"),
            ["line 3: ", "autocontinue", "('yes')"],
        ),
        ("QGC WPL 110\n", ["no home line"]),
        ("QGC WPL 100\n0\t1\t0\t16\t0\t0\t0\t0\t47.3\t8.5\t488\t1\n", ["line 1: ", "QGC WPL 110"]),
        (
            WPL_HOME + _row("1 0 3 16 0 0 0 0 95 8.5 50 1"),
            ["item 0 (line 3): ", "latitude", "(95.0)"],
        ),
        (
            WPL_HOME + _row("1 0 2 177 9 1 0 0 0 0 0 1"),
            ["item 0 (line 3): ", "DO_JUMP target", "(9.0)"],
        ),
    ],
    ids=[
        "short-line",
        "not-a-number",
        "seq-order",
        "autocontinue",
        "no-home",
        "version",
        "latitude",
        "jump",
    ],
)
def test_wpl_errors(write_doc: PlanWriter, text: str, expected: list[str]) -> None:
    path = write_doc(text, "bad.waypoints")
    _refused_in_one_line(path, expected)
