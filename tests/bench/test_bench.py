"""``air-sitl bench`` end to end: a real short flight, built-in methods, and the example
localizer as an external program on the bus in lockstep; resume; bad options."""

from __future__ import annotations

import json
import os
import shutil
import sys
from pathlib import Path

import pytest
import short_plans
import yaml
from cli_errors import one_line_error

from air_sitl.bench.config import parse_localizer
from air_sitl.cli import main
from air_sitl.localize.external import localizer_argv
from air_sitl.state import GeoPoint
from air_sitl.sweep.results import RESULTS, read_rows

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    # "U...": flown over the urban map, like the AIR urban scenarios. About 350 frames (each
    # costs about 15 ms of CPU across the bench's flights and methods), at 120 m: nothing reads
    # the altitude in the name, and bench flies from the ground, where the climb to 200 m was
    # most of each flight's 100 simulated seconds.
    short_plans.write_short_plan(folder / "UT-200.plan", HOME, leg_m=100.0, alt_m=120.0)
    return folder


@pytest.fixture(scope="module")
def bench(missions: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bench") / "b"
    assert _run_bench(missions, out, "--name ex --quiet") == 0
    return out


def _run_bench(missions: Path, out: Path, example_options: str, *extra: str) -> int:
    """``air-sitl bench`` of UT-200: two methods and the example localizer as ``ex``."""
    example = f"{sys.executable} {ROOT / 'bridges' / 'example_localizer.py'} {example_options}"
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "deadreckon,vo", "--missions",
        str(missions), "--map-date", "1", "--localizer", f"ex={example}", "--out", str(out),
        "--quiet", *extra,
    ]  # fmt: skip
    return main(argv)


def test_leaderboard_has_every_method_and_the_external_localizer(bench: Path) -> None:
    board = json.loads((bench / "leaderboard.json").read_text())
    assert board["methods"] == ["deadreckon", "vo", "ex"]
    rows = {row["method"]: row for row in board["rows"]}
    for name in ("deadreckon", "vo", "ex"):
        row = rows[name]
        assert row["scenario"] == "UT-200" and row["error"] is None, row
        assert row["availability"] is not None and row["availability"] > 0.9, row
        assert row["median_m"] is not None and 0.0 <= row["median_m"] < 100.0, row
    # The external run answered every frame of the same flight, in lockstep.
    report = json.loads((bench / "reports" / "UT-200" / "ex.json").read_text())["report"]
    assert report["estimated_frames"] == report["frames"] > 300
    archive = bench / "archives" / "UT-200"
    assert (archive / "estimates" / "ex.csv").is_file()
    assert "estimates/ex.csv" in json.loads((archive / "manifest.json").read_text())["files"]
    md = (bench / "leaderboard.md").read_text()
    assert "| deadreckon |" in md and "| ex |" in md and "recall@25 m" in md
    png = (bench / "error_boxes.png").read_bytes()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000


def test_a_second_run_resumes_without_measuring_again(
    bench: Path, missions: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    reports = sorted((bench / "reports").rglob("*.json"))
    before = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in reports}
    files = {p: p.read_bytes() for p in bench.rglob("*") if p.is_file()}
    capsys.readouterr()
    # Without --resume: refused, naming it (the same bench), nothing changed.
    assert _run_bench(missions, bench, "--name ex --quiet") == 2
    assert "--resume continues it, --overwrite replaces it" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in bench.rglob("*") if p.is_file()} == files
    assert _run_bench(missions, bench, "--name ex --quiet", "--resume") == 0
    assert {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in reports} == before


def test_endpoint_is_appended_or_substituted() -> None:
    plain = parse_localizer('mine=python my_loc.py --name "my loc"')
    assert plain.argv == ("python", "my_loc.py", "--name", "my loc")
    assert localizer_argv(plain, "tcp/127.0.0.1:5")[-2:] == ["--zenoh-connect", "tcp/127.0.0.1:5"]
    placed = parse_localizer("x=run --bus {endpoint} --fast")
    expected = ["run", "--bus", "tcp/127.0.0.1:5", "--fast"]
    assert localizer_argv(placed, "tcp/127.0.0.1:5") == expected


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        (["--methods", "deadreckon,teleport"], "unknown method 'teleport'"),
        (["--methods", "vo,vo"], "named twice"),
        (["--localizer", "no-equals-sign"], "expected NAME=COMMAND"),
        (["--localizer", "vo=python x.py"], "--localizer vo: the name is used twice"),
        (["--localizer", "x="], "--localizer x: the command is empty"),
        (["--scenarios", "ZZ-100"], "ZZ-100 has no plan"),
        (["-j", "0"], "-j"),
        (["--wait-timeout", "0"], "--wait-timeout: '0' is not a number > 0"),
        (["--wait-timeout", "soon"], "--wait-timeout: 'soon' is not a number > 0"),
    ],
)
def test_bad_options_get_one_line_and_exit_2(
    extra: list[str],
    expected: str,
    missions: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    argv = ["bench", "--scenarios", "UT-200", "--methods", "vo", "--missions", str(missions)]
    argv += ["--map-date", "1", "--out", str(tmp_path / "b"), *extra]
    assert expected in one_line_error(argv, capsys)
    assert not (tmp_path / "b").exists()  # nothing flown or written


def test_archives_of_another_flight_are_refused_not_reused(
    bench: Path, missions: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "deadreckon", "--missions",
        str(missions), "--map-date", "1", "--out", str(bench), "--seed", "1", "--quiet",
    ]  # fmt: skip
    files = {p: p.read_bytes() for p in bench.rglob("*") if p.is_file()}
    capsys.readouterr()
    assert main(argv) == 2  # another bench: refused, and --resume is not offered
    err = capsys.readouterr().err.strip()
    assert "a bench of other inputs: runs, methods, localizers differ" in err, err
    assert "--resume" not in err and "--overwrite replaces it" in err
    assert main([*argv, "--resume"]) == 2
    assert "--resume: a bench of other inputs" in capsys.readouterr().err
    assert {p: p.read_bytes() for p in bench.rglob("*") if p.is_file()} == files


def test_overwrite_replaces_an_earlier_bench(tmp_path: Path) -> None:
    # What is flown does not matter here: a UT-200 of a 20 m leg at 60 m (130 frames, 25 s).
    missions = tmp_path / "missions"
    missions.mkdir()
    short_plans.write_short_plan(missions / "UT-200.plan", HOME, leg_m=20.0, alt_m=60.0)
    out = tmp_path / "b"
    (out / "archives").mkdir(parents=True)
    (out / "archives" / "stray.txt").write_text("from before")
    (out / "bench.yaml").write_text("runs: []\n")
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "deadreckon", "--missions",
        str(missions), "--map-date", "1", "--out", str(out), "--quiet", "--overwrite",
    ]  # fmt: skip
    assert main(argv) == 0
    assert not (out / "archives" / "stray.txt").exists()
    board = json.loads((out / "leaderboard.json").read_text())
    assert board["methods"] == ["deadreckon"]


def test_a_bench_is_a_sweep_with_its_spec_and_rows(bench: Path) -> None:
    text = (bench / "bench.yaml").read_text()
    assert text.startswith("runs:\n")  # no base: no --wait-timeout given, the SPEC of before
    spec = yaml.safe_load(text)
    assert spec["runs"] == [{"scenario": "UT-200", "map-date": 1, "seed": 0}]
    assert spec["methods"] == ["deadreckon", "vo"] and list(spec["localizers"]) == ["ex"]
    (row,) = read_rows(bench / RESULTS)
    assert row["error"] is None and row["archive"] == "archives/UT-200"
    # The methods matched the reference map the SPEC names (bench.yaml, then the run's task).
    assert spec["reference-date"] == 0 and row["reference_date"] == 0
    assert list(row["eval"]) == ["deadreckon", "vo", "ex"]
    for name, report in row["eval"].items():
        saved = json.loads((bench / "reports" / "UT-200" / f"{name}.json").read_text())
        assert saved["report"] == report


def _linked_archives(bench: Path, out: Path) -> None:
    """The bench's archive in ``out`` (hard links: nothing measured yet in that folder)."""
    shutil.copytree(
        bench / "archives",
        out / "archives",
        copy_function=os.link,
        ignore=shutil.ignore_patterns("estimates", "*.log"),
    )


def test_wait_timeout_reaches_the_lockstep_flights(
    bench: Path, missions: Path, tmp_path: Path
) -> None:
    """A localizer that never subscribes: its lockstep flight gives up after --wait-timeout
    (fly's default is 10 s), and bench.yaml records the option as the SPEC's base."""
    out = tmp_path / "b"
    _linked_archives(bench, out)
    silent = f"{sys.executable} -c 'import time; time.sleep(600)'"  # SIGINT's default ends it
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "deadreckon", "--missions",
        str(missions), "--map-date", "1", "--localizer", f"silent={silent}",
        "--wait-timeout", "1.5", "--out", str(out), "--quiet",
    ]  # fmt: skip
    assert main(argv) == 1  # the silent localizer's cell failed
    rows = {r["method"]: r for r in json.loads((out / "leaderboard.json").read_text())["rows"]}
    assert rows["deadreckon"]["error"] is None
    error = rows["silent"]["error"]
    assert "nobody subscribed to" in error and "within 1.5 s" in error, error
    spec = yaml.safe_load((out / "bench.yaml").read_text())
    assert spec["base"] == {"wait-timeout": 1.5}
    assert spec["runs"] == [{"scenario": "UT-200", "map-date": 1, "seed": 0}]


def test_the_same_leaderboard_on_a_local_ray(bench: Path, missions: Path, tmp_path: Path) -> None:
    pytest.importorskip("ray", reason="ray is not installed (pip install 'air-sitl[ray]')")
    out = tmp_path / "b"
    _linked_archives(bench, out)  # the same archive, measured on Ray
    argv = [
        "bench", "--scenarios", "UT-200", "--methods", "deadreckon,vo", "--missions",
        str(missions), "--map-date", "1", "--out", str(out), "--ray", "--quiet",
    ]  # fmt: skip
    assert main(argv) == 0
    on_ray = json.loads((out / "leaderboard.json").read_text())
    on_pool = json.loads((bench / "leaderboard.json").read_text())
    speed = ("frames_per_s",)
    for rows in (on_ray["rows"], on_pool["rows"]):
        for row in rows:
            for key in speed:
                row.pop(key)
    assert on_ray["rows"] == [r for r in on_pool["rows"] if r["method"] != "ex"]
