"""The one overwrite rule (air_sitl.outdir) for every command that writes a folder or a file:
a non-empty one of another run is refused in one line, exit 2, not a byte changed; ``--resume``
continues the same inputs (and is named only then); ``--overwrite`` replaces (nothing of the
old run stays). bench and map fetch: tests/bench/test_bench.py, tests/maps/test_stac.py."""

from __future__ import annotations

import csv
import re
from pathlib import Path

import pytest
import yaml
from cli_errors import one_line_error
from short_plans import write_short_plan

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from air_sitl.sweep.results import RESULTS, read_rows

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` with its bytes (what a refusal must leave alone)."""
    return {
        str(p.relative_to(root)): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()
    }


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_short_plan(folder / "UC-200.plan", HOME, leg_m=20.0, leg="north")
    write_short_plan(folder / "FC-200.plan", HOME, leg_m=20.0, leg="east")
    return folder


@pytest.fixture(scope="module")
def flown(missions: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("fly") / "a"
    assert main(fly(missions, out)) == 0
    return out


def fly(missions: Path, out: Path, *extra: str) -> list[str]:
    return [
        "fly",
        str(missions / "UC-200.plan"),
        "--air-start",
        "--quiet",
        "--out",
        str(out),
        *extra,
    ]


def test_fly_refuses_another_run_names_resume_only_for_the_same_inputs(
    missions: Path, flown: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    before = snapshot(flown)
    other = one_line_error(fly(missions, flown, "--seed", "3"), capsys)
    assert "holds another run" in other and "--overwrite replaces it" in other, other
    assert "--resume" not in other and "flight differs" in other, other
    same = one_line_error(fly(missions, flown), capsys)
    assert "--resume continues it, --overwrite replaces it" in same, same
    wrong = one_line_error(fly(missions, flown, "--seed", "3", "--resume"), capsys)
    assert "--resume: a complete archive of other inputs (flight differs)" in wrong, wrong
    assert snapshot(flown) == before
    assert main(fly(missions, flown, "--resume")) == 0  # the same inputs: complete, nothing to do
    assert snapshot(flown) == before


def test_fly_overwrite_replaces_the_old_run_entirely(
    missions: Path, flown: Path, tmp_path: Path
) -> None:
    out = tmp_path / "b"
    out.mkdir()
    for path in flown.rglob("*"):
        target = out / path.relative_to(flown)
        target.mkdir(exist_ok=True) if path.is_dir() else target.write_bytes(path.read_bytes())
    (out / "stray.txt").write_text("from before")
    (out / "metadata.csv").write_text("not the old rows\n")
    assert main(fly(missions, out, "--overwrite")) == 0
    after = snapshot(out)
    assert after.keys() == snapshot(flown).keys()  # never a mix of the two runs
    assert after["metadata.csv"] == (flown / "metadata.csv").read_bytes()


def test_no_camera_run_is_refused_without_offering_resume(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "n"
    assert main(fly(missions, out, "--no-camera")) == 0
    before = snapshot(out)
    line = one_line_error(fly(missions, out, "--no-camera"), capsys)
    assert line.endswith(
        "folder exists and is not empty: --overwrite replaces it, or choose another --out"
    )
    assert snapshot(out) == before
    (out / "stray.txt").write_text("from before")
    assert main(fly(missions, out, "--no-camera", "--overwrite")) == 0
    assert snapshot(out).keys() == before.keys()


def dataset(missions: Path, root: Path) -> list[str]:
    return ["dataset", "--missions", str(missions), "--air-start", "--quiet", "--out", str(root)]


def stats_rows(root: Path) -> dict[str, dict[str, str]]:
    with (root / "stats.csv").open(newline="") as f:
        return {r["scenario"]: r for r in csv.DictReader(f)}


def test_dataset_keeps_earlier_scenarios_refuses_overwrites_and_resumes(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "air"
    argv = dataset(missions, root)
    assert main([*argv, "--scenarios", "UC-200"]) == 0
    assert main([*argv, "--scenarios", "FC-200"]) == 0  # beside it: its row stays in the table
    rows = stats_rows(root)
    assert set(rows) == {"UC-200", "FC-200", "total"}
    assert int(rows["total"]["images"]) == int(rows["UC-200"]["images"]) + int(
        rows["FC-200"]["images"]
    )
    before = snapshot(root)
    other = one_line_error([*argv, "--scenarios", "UC-200", "--seed", "5"], capsys)
    assert "UC-200: folder holds another run" in other and "--resume" not in other, other
    same = one_line_error([*argv, "--scenarios", "UC-200"], capsys)
    assert "--resume continues it" in same, same
    assert snapshot(root) == before
    assert main([*argv, "--scenarios", "UC-200,FC-200", "--resume"]) == 0
    assert snapshot(root) == before  # both complete: nothing written again
    assert main([*argv, "--scenarios", "UC-200", "--seed", "5", "--overwrite"]) == 0
    assert sorted(p.name for p in root.iterdir()) == ["UC-200", "stats.csv"]
    assert set(stats_rows(root)) == {"UC-200", "total"}


def test_map_make_refuses_an_existing_file_and_overwrites_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "m.tif"
    argv = ["map", "make", "urban", "--size-m", "60", "60", "--out", str(out)]
    assert main(argv) == 0
    # Its progress line: a rate from the work's start (the first block's end once gave 1.9T).
    rate = re.search(r"([\d.]+)([kMGT]?) px/s", capsys.readouterr().err)
    assert rate is not None
    assert float(rate[1]) * {"": 1, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12}[rate[2]] < 1e9
    made = out.read_bytes()
    out.write_bytes(b"not a map")
    line = one_line_error(argv, capsys)
    assert "exists already (--overwrite replaces it" in line and "--resume" not in line, line
    assert out.read_bytes() == b"not a map"
    assert main([*argv, "--overwrite"]) == 0
    assert out.read_bytes() == made


def test_export_refuses_existing_outputs_and_overwrites_them(
    flown: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tum = tmp_path / "t.txt"
    tum.write_text("old\n")
    capsys.readouterr()
    line = one_line_error(["export", str(flown), "--tum", str(tum)], capsys)
    assert "t.txt: exists already (--overwrite replaces it" in line, line
    assert tum.read_text() == "old\n"
    assert main(["export", str(flown), "--tum", str(tum), "--overwrite"]) == 0
    assert tum.read_text().count("\n") > 30
    capsys.readouterr()
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "old.mcap").write_bytes(b"old")
    one_line_error(["export", str(flown), "--rosbag2", str(bag)], capsys)
    assert snapshot(bag) == {"old.mcap": b"old"}
    assert main(["export", str(flown), "--rosbag2", str(bag), "--overwrite"]) == 0
    assert not (bag / "old.mcap").exists() and (bag / "metadata.yaml").is_file()


def test_sweep_refuses_another_spec_resumes_its_own_and_overwrites(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def spec(name: str, seeds: list[int]) -> Path:
        content = {
            "base": {"plan": str(missions / "UC-200.plan"), "air-start": True},
            "axes": {"seed": seeds},
        }
        path = tmp_path / name
        path.write_text(yaml.safe_dump(content, sort_keys=False), encoding="utf-8")
        return path

    one, two = spec("one.yaml", [1]), spec("two.yaml", [2])
    out = tmp_path / "s"
    argv = ["sweep", "--out", str(out), "--quiet"]
    assert main(["sweep", str(one), *argv[1:]]) == 0
    before = snapshot(out)
    capsys.readouterr()
    other = one_line_error(["sweep", str(two), *argv[1:]], capsys)
    assert "a sweep of other inputs: spec, runs differ" in other and "--resume" not in other
    same = one_line_error(["sweep", str(one), *argv[1:]], capsys)
    assert "--resume continues it" in same, same
    assert snapshot(out) == before
    assert main(["sweep", str(one), *argv[1:], "--resume"]) == 0  # nothing left to run
    assert (out / RESULTS).read_bytes() == before[RESULTS]
    assert main(["sweep", str(two), *argv[1:], "--overwrite"]) == 0
    assert [r["options"]["seed"] for r in read_rows(out / RESULTS)] == [2]
    assert len(list((out / "runs").iterdir())) == 1  # the old run's folder is gone
