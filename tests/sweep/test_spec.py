"""The SPEC: runs from axes and explicit runs, ids, and one line naming the key for bad input."""

from __future__ import annotations

from pathlib import Path

import pytest
import short_plans
import yaml

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from air_sitl.sweep.errors import SweepError
from air_sitl.sweep.spec import load_spec, run_id

HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("spec")
    (root / "plans").mkdir()
    short_plans.write_short_plan(root / "plans" / "UT-200.plan", HOME, leg_m=30.0)
    return root


def write(folder: Path, content: object, name: str = "s.yaml") -> Path:
    path = folder / name
    path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
    return path


BASE = {"plan": "plans/UT-200.plan", "air-start": True, "max-sim-time": 60}


def test_axes_make_the_product_and_runs_add_to_it(folder: Path) -> None:
    spec = load_spec(
        write(
            folder,
            {
                "base": BASE,
                "axes": {"map-date": [0, 1], "wind": ["0@0", "5@270"], "seed": [1, 2]},
                "runs": [{"seed": 9}, {"map-date": 0, "wind": "0@0", "seed": 1}],  # 2nd: a dup
                "methods": ["deadreckon"],
            },
        )
    )
    assert len(spec.runs) == 9
    assert len({r.id for r in spec.runs}) == 9
    first = spec.runs[0]
    assert first.options == {**BASE, "map-date": 0, "wind": "0@0", "seed": 1}
    assert first.id == run_id(first.options)
    assert first.plan_path == (folder / "plans" / "UT-200.plan").resolve()
    assert "--air-start" in first.argv and "--wind=0@0" in first.argv
    assert "--render-workers=0" in first.argv  # one thread per run unless the SPEC says
    assert first.seed == 1
    assert spec.methods == ("deadreckon",)
    assert spec.axes == ("map-date", "wind", "seed")


def test_ids_do_not_depend_on_key_order() -> None:
    assert run_id({"a": 1, "b": [1, 2]}) == run_id({"b": [1, 2], "a": 1})
    assert run_id({"a": 1}) != run_id({"a": 2})


def test_scenario_names_a_plan_of_the_missions_folder(folder: Path) -> None:
    path = write(folder, {"base": {"scenario": "UT-200", "air-start": True}})
    spec = load_spec(path, missions=folder / "plans")
    assert spec.runs[0].plan_label == "UT-200"
    assert spec.runs[0].plan_path.name == "UT-200.plan"


BAD = [
    ({"base": {**BASE, "altitud": 5}}, "base.altitud: unknown option 'altitud'"),
    ({"base": BASE, "axes": {"seed": []}}, "axes.seed: the axis is empty"),
    ({"base": BASE, "axes": {"seed": 3}}, "axes.seed: expected a list of values"),
    ({"base": {**BASE, "air-start": "yes"}}, "base.air-start: air-start is a flag"),
    ({"base": {**BASE, "wind": {"speed": 5}}}, "base.wind: wind takes one value, got dict"),
    ({"base": BASE, "axes": {"wind": ["0@0", "fast"]}}, "axes.wind[1], run 2"),
    ({"base": BASE, "axes": {"map-seed": [1, "abc"]}}, "axes.map-seed[1], run 2"),
    ({"base": BASE, "runs": [{"altitude-offset": -500}]}, "runs[0].altitude-offset, run 1"),
    ({"base": {**BASE, "out": "x"}}, "base.out: 'out' is set by the sweep itself"),
    ({"base": {**BASE, "plan": "nowhere.plan"}}, "base.plan, run 1"),
    ({"base": BASE, "methods": ["nosuch"]}, "methods[0]: unknown method 'nosuch'"),
    ({"base": BASE, "axis": {}}, "unknown key 'axis'"),
    ({"base": BASE, "reference-date": "0"}, "reference-date: expected a map date 0-99, got '0'"),
    ({"base": BASE, "reference-date": -1}, "reference-date: expected a map date 0-99, got -1"),
    ({"axes": {"seed": [1]}}, "no plan"),
]


@pytest.mark.parametrize(("content", "expected"), BAD, ids=[b[1][:30] for b in BAD])
def test_a_bad_spec_is_one_line_naming_the_key(
    folder: Path, content: object, expected: str
) -> None:
    path = write(folder, content)
    with pytest.raises(SweepError) as info:
        load_spec(path)
    text = str(info.value)
    assert expected in text, text
    assert text.startswith(str(path)) and "\n" not in text


def test_the_command_prints_one_line_and_exits_2(
    folder: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = write(folder, {"base": BASE, "axes": {"seed": []}})
    assert main(["sweep", str(path), "--out", str(folder / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "axes.seed: the axis is empty" in err[0]
    assert not (folder / "out").exists()


def test_archives_go_where_the_spec_says(folder: Path) -> None:
    from air_sitl.sweep import make_tasks

    path = write(folder, {"base": BASE, "archives": "shared/runs"})
    spec = load_spec(path)
    assert spec.archives == (folder / "shared" / "runs").resolve()
    (task,) = make_tasks(spec, folder / "out", keep="none")
    assert task.archive == str(folder.resolve() / "shared" / "runs" / task.id)
    assert task.archive_label == task.archive  # outside the sweep folder: the full path
    assert task.plan_text == (folder / "plans" / "UT-200.plan").read_bytes()
    assert task.keep == "none"


def test_reference_date_reaches_every_run(folder: Path) -> None:
    """``reference-date: 0``: map matchers match date 0 whatever date each run flies over
    (without it, a run over date 0 would match date 1), and the rows say so."""
    from air_sitl.sweep import make_tasks

    axes = {"map-date": [0, 1, 2]}
    spec = load_spec(write(folder, {"base": BASE, "axes": axes, "reference-date": 0}))
    assert [t.reference_date for t in make_tasks(spec, folder / "out")] == [0, 0, 0]
    plain = load_spec(write(folder, {"base": BASE, "axes": axes}))
    assert [t.reference_date for t in make_tasks(plain, folder / "out")] == [None] * 3
