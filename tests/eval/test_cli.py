"""``air-sitl eval`` on real flown archives: report, JSON, sources, requirements, bad input."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from air_sitl.cli import main
from air_sitl.dataset.estimates import fill_svo_columns
from air_sitl.eval import evaluate, evaluate_many
from air_sitl.frames import ned2geodetic

from .helpers import HEADER, rows, truth_of, write_csv, write_estimate

pytestmark = pytest.mark.integration

SPEC_KEYS = [
    "v", "archive", "estimate", "alignment", "frames", "estimated_frames", "availability",
    "fix_rate", "longest_without_fix_s", "distance_m", "horizontal_error_m", "error_3d_m",
    "recall", "final_error_m", "drift_pct", "rpe", "straight", "turn", "turn_straight_rpe_ratio",
    "latency_ms", "time_to_first_fix_s", "longest_outage_s",
]  # fmt: skip
STATS = ["mean", "median", "rmse", "p95", "max"]


def noisy(archive: Path, name: str = "noisy", sigma_m: float = 4.0, drop: float = 0.1) -> Path:
    truth = truth_of(archive)
    rng = np.random.default_rng(7)
    keep = np.flatnonzero(rng.random(truth.frames) >= drop)
    pos = truth.pos_enu_m[keep] + rng.normal(0.0, sigma_m, (keep.size, 3))
    latency = rng.gamma(2.0, 5.0, keep.size)
    return write_estimate(archive, name, pos, keep, latency)


def run(*args: str) -> int:
    return main(["eval", *args])


def test_turns_on_a_circle_and_a_line(circle: Path, line: Path) -> None:
    c = evaluate(circle, "svo")
    assert c["turn"]["frames"] > 0.9 * c["frames"]
    assert c["turn"]["frames"] + c["straight"]["frames"] == c["frames"]
    assert 900.0 < c["distance_m"] < 1100.0  # AIR's UC-200: about 1 km around
    straight = evaluate(line, "svo")
    assert straight["straight"]["frames"] > 0.9 * straight["frames"]
    assert 380.0 < straight["distance_m"] < 420.0


def test_report_of_a_noisy_estimate_has_the_spec_keys(line: Path, tmp_path: Path) -> None:
    noisy(line)
    out = tmp_path / "r.json"
    assert run(str(line), "--estimate", "noisy", "--json", str(out)) == 0
    report = json.loads(out.read_text())
    assert isinstance(report, dict)
    assert list(report) == SPEC_KEYS
    assert list(report["horizontal_error_m"]) == STATS == list(report["error_3d_m"])
    assert list(report["recall"]) == ["5m", "10m", "25m", "50m"]
    assert list(report["rpe"]) == ["100m", "500m"]
    assert list(report["straight"]) == ["frames", "horizontal_error_m", "rpe"]
    assert report["estimate"] == "noisy" and report["alignment"] == "none"
    assert 0.85 < report["availability"] < 0.95
    assert report["fix_rate"] is None and report["longest_without_fix_s"] is None  # not said
    # 2-D gaussian with sigma 4 m: Rayleigh, rmse = 4 * sqrt(2)
    assert report["horizontal_error_m"]["rmse"] == pytest.approx(4.0 * 2**0.5, rel=0.1)
    assert report["latency_ms"]["median"] == pytest.approx(8.4, rel=0.2)
    assert report["rpe"]["500m"] == {"mean": None, "rmse": None}  # a 400 m leg
    assert report["drift_pct"] == pytest.approx(
        report["final_error_m"] / report["distance_m"] * 100.0
    )


def test_json_is_a_list_for_several_estimates(line: Path, tmp_path: Path) -> None:
    noisy(line, "a")
    noisy(line, "b", sigma_m=20.0, drop=0.0)
    out = tmp_path / "r.json"
    assert run(str(line), "--estimate", "a", "--estimate", "b", "--json", str(out)) == 0
    reports = json.loads(out.read_text())
    assert [r["estimate"] for r in reports] == ["a", "b"]
    assert reports == evaluate_many(line, ["a", "b"])


def test_require_passes_and_fails(line: Path, capsys: pytest.CaptureFixture[str]) -> None:
    noisy(line, "good", sigma_m=2.0, drop=0.0)
    noisy(line, "bad", sigma_m=30.0, drop=0.0)
    ok = ("--require", "horizontal_error_m.rmse<=20", "--require", "recall.25m>=0.9")
    assert run(str(line), "--estimate", "good", *ok) == 0
    met = capsys.readouterr().err.strip().splitlines()  # a passing gate says so
    assert met[0].startswith("air-sitl: requirement met: good: horizontal_error_m.rmse = ")
    assert met[1].startswith("air-sitl: requirement met: good: recall.25m = ") and len(met) == 2
    assert run(str(line), "--estimate", "good", "--estimate", "bad", *ok) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2
    assert all(x.startswith("air-sitl: requirement failed: bad: ") for x in err)
    assert "horizontal_error_m.rmse = " in err[0] and "required <= 20" in err[0]
    assert "recall.25m = " in err[1] and "required >= 0.9" in err[1]


@pytest.mark.parametrize(
    ("expr", "says"),
    [
        ("horizontal_error_m.rmse=<20", "expected PATH OP NUMBER"),
        ("horizontal_error_m.rmse<=twenty", "'twenty' is not a finite number"),
        ("horizontal_error_m.rsme<=20", "no key 'rsme'"),
        ("recall<=1", "recall is not a number"),
    ],
)
def test_a_bad_requirement_is_a_user_error(
    line: Path, capsys: pytest.CaptureFixture[str], expr: str, says: str
) -> None:
    assert run(str(line), "--estimate", "svo", "--require", expr) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and says in err[0], err
    if "no key" in says:  # the line lists the keys it takes
        assert "; the keys: frames, estimated_frames, availability, " in err[0], err
        assert "horizontal_error_m.rmse" in err[0] and "recall.25m" in err[0]


def test_a_null_figure_fails_its_requirement(
    line: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(str(line), "--estimate", "svo", "--require", "horizontal_error_m.max<=5") == 1
    err = capsys.readouterr().err
    assert "svo: horizontal_error_m.max is null" in err
    # A simulated archive's SvoX..Z are empty: eval says why it scores nothing.
    assert "note: svo: the archive's SvoX..SvoZ are empty" in err, err


def test_svo_columns_of_a_folder_and_of_an_original_air_zip(line: Path, tmp_path: Path) -> None:
    truth = truth_of(line)
    filled = {k: tuple(truth.pos_enu_m[k] + (3.0, 4.0, 0.0)) for k in range(0, truth.frames, 2)}
    fill_svo_columns(line, filled)  # type: ignore[arg-type]
    report = evaluate(line, "svo")
    assert report["estimated_frames"] == len(filled)
    assert report["horizontal_error_m"]["max"] == pytest.approx(5.0, abs=1e-3)
    # an original AIR archive: metadata.csv and images in a zip, no frames.csv (row k at k/50 s)
    zipped = tmp_path / "air.zip"
    with zipfile.ZipFile(zipped, "w") as z:
        z.write(line / "metadata.csv", "UL-T/metadata.csv")
    original = evaluate(zipped, "svo")
    assert original["estimated_frames"] == len(filled)
    assert original["horizontal_error_m"]["rmse"] == pytest.approx(5.0, abs=1e-3)
    assert original["latency_ms"] == {"median": None, "p95": None}


def test_tum_round_trip_through_export(line: Path, tmp_path: Path) -> None:
    tum = tmp_path / "truth.txt"
    assert main(["export", str(line), "--tum", str(tum)]) == 0
    report = evaluate(line, str(tum))
    assert report["availability"] == 1.0
    assert report["error_3d_m"]["max"] < 1e-3  # the 0.1 mm of the files
    noisy(line, "n")
    est_tum = tmp_path / "n.txt"
    assert main(["export", str(line), "--tum", str(est_tum), "--estimate", "n"]) == 0
    by_time, by_frame = evaluate(line, str(est_tum)), evaluate(line, "n")
    assert by_time["estimated_frames"] == by_frame["estimated_frames"]
    assert by_time["horizontal_error_m"]["rmse"] == pytest.approx(
        by_frame["horizontal_error_m"]["rmse"], abs=1e-3
    )
    assert by_time["latency_ms"]["median"] is None  # TUM carries no latency


def test_a_csv_path_outside_the_archive_and_sim3(line: Path, tmp_path: Path) -> None:
    truth = truth_of(line)
    vo = 0.3 * truth.pos_enu_m  # monocular VO: right shape, wrong scale
    path = write_csv(tmp_path / "vo.csv", rows(truth, vo))
    assert evaluate(line, str(path), "sim3")["error_3d_m"]["max"] < 1e-3
    assert evaluate(line, str(path), "se3")["error_3d_m"]["rmse"] > 10.0


def test_plots_are_written(line: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    noisy(line)
    out = tmp_path / "plots"
    assert run(str(line), "--estimate", "noisy", "--estimate", "svo", "--plots", str(out)) == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == ["error_cdf.png", "error_distance.png", "track_noisy.png", "track_svo.png"]
    assert all((out / n).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for n in names)


def _bad(archive: Path, text: str) -> Path:
    return write_csv(archive / "estimates" / "bad.csv", [text], header=HEADER)


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ("", "bad.csv: empty file"),
        ("T,3,abc,1.0,200.0,,,,,,,,,", "bad.csv: line 2: east_m 'abc' is not a number"),
        ("T,3,inf,1.0,200.0,,,,,,,,,", "bad.csv: line 2: east_m 'inf' is not a finite number"),
        ("T,3,1.0,nan,200.0,,,,,,,,,", "bad.csv: line 2: east_m,north_m,up_m = 1.0,nan,200.0"),
        ("T,3,1.0,,200.0,,,,,,,,,", "bad.csv: line 2: east_m,north_m,up_m = 1.0,'',200.0"),
        ("T,3,1,2,3,,,,,,,,,\nU,3,1,2,3,,,,,,,,,", "bad.csv: line 3: frame 3 already estimated"),
        ("T,99999,1,2,3,,,,,,,,,", "bad.csv: line 2: frame 99999 is outside the archive"),
        ("U,4,1,2,3,,,,,,,,,\nT,3,1,2,3,,,,,,,,,", "bad.csv: line 3: time"),
        ("T,3,1,2,3,,,,,,,,x,", "bad.csv: line 2: latency_wall_ms 'x' is not a number"),
    ],
    ids=["empty", "text", "inf", "partial-nan", "partial-empty", "duplicate", "outside",
         "order", "latency-text"],
)  # fmt: skip
def test_bad_estimate_csv_is_one_line_and_exit_2(
    line: Path, capsys: pytest.CaptureFixture[str], body: str, says: str
) -> None:
    truth = truth_of(line)
    path = line / "estimates" / "bad.csv"
    path.parent.mkdir(exist_ok=True)
    text = body.replace("T", str(truth.t_ns[3])).replace("U", str(truth.t_ns[4]))
    path.write_text(f"{HEADER}\n{text}\n" if body else "", encoding="ascii")
    assert run(str(line), "--estimate", "bad") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    assert says in err[0], err[0]
    assert str(path) in err[0]


def test_a_bad_fix_cell_is_one_line_and_exit_2(
    line: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    truth = truth_of(line)
    good = rows(truth, truth.pos_enu_m[:1], np.array([0]))
    write_csv(
        line / "estimates" / "badfix.csv",
        [good[0] + ",1", good[0].replace(f"{truth.t_ns[0]},0,", f"{truth.t_ns[1]},1,") + ",yes"],
        header=HEADER + ",fix",
    )
    assert run(str(line), "--estimate", "badfix") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "badfix.csv: line 3: fix 'yes' is not 1, 0 or empty" in err[0], err


def test_all_nan_and_all_empty_rows_are_no_estimate(line: Path) -> None:
    truth = truth_of(line)
    good = rows(truth, truth.pos_enu_m[:2], np.array([0, 1]))
    no = [f"{truth.t_ns[2]},2,nan,nan,nan,,,,,,,,,", f"{truth.t_ns[3]},3,,,,,,,,,,,,"]
    write_csv(line / "estimates" / "gaps.csv", good + no)
    report = evaluate(line, "gaps")
    assert report["estimated_frames"] == 2


@pytest.mark.parametrize(
    ("body", "says"),
    [
        ("", "empty file"),
        ("{t1} 1 2 3 0 0 0\n", "line 1: 7 columns"),
        ("# t x y z qx qy qz qw\n{t1} 1 2 3 0 0 0 1 5\n", "line 2: 9 columns"),
        ("{t1} 1 2 inf 0 0 0 1\n", "line 1: z 'inf' is not a finite number"),
        ("{t1} 1 2 3 0 0 0 1\n{t0} 1 2 3 0 0 0 1\n", "line 2: time {t0_ns} ns is not after"),
        ("99999.0 1 2 3 0 0 0 1\n", "line 1: time 99999.000000000 s is outside"),
    ],
    ids=["empty", "7-columns", "9-columns", "inf", "order", "outside"],
)
def test_bad_tum_is_one_line_and_exit_2(
    line: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], body: str, says: str
) -> None:
    t0_ns = int(truth_of(line).t_ns[0])
    values = {"t0": f"{t0_ns / 1e9:.3f}", "t1": f"{t0_ns / 1e9 + 1:.3f}", "t0_ns": str(t0_ns)}
    path = tmp_path / "bad.txt"
    path.write_text(body.format(**values))
    assert run(str(line), "--estimate", str(path)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(path) in err[0] and says.format(**values) in err[0], err


def test_an_archive_without_truth_and_an_unknown_source(
    line: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(str(line), "--estimate", "nobody") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nobody: no such estimate" in err[0]
    header = (line / "metadata.csv").read_text().splitlines()[0]
    (line / "metadata.csv").write_text(header + "\n")
    (line / "frames.csv").unlink()
    assert run(str(line), "--estimate", "svo") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "metadata.csv: no frames, so no truth" in err[0], err


def test_terminal_table_has_a_column_per_estimate(
    line: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    noisy(line, "mine")
    assert run(str(line), "--estimate", "mine", "--estimate", "svo", "--align", "posyaw") == 0
    out = capsys.readouterr().out.splitlines()
    assert len(out) <= 40
    assert out[1].split() == ["mine", "svo"]
    assert out[2].split()[-2:] == ["posyaw", "posyaw"]


def test_lat_lon_estimates_are_scored_from_the_archive_home(line: Path) -> None:
    home = json.loads((line / "manifest.json").read_text())["home"]
    truth = truth_of(line)
    lines = []
    for k in range(0, truth.frames, 3):
        e, n, u = truth.pos_enu_m[k] + (0.0, 7.0, 0.0)
        lat, lon, alt = ned2geodetic(n, e, -u, home["lat_deg"], home["lon_deg"], home["alt_amsl_m"])
        lines.append(f"{truth.t_ns[k]},{k},nan,nan,nan,{lat:.9f},{lon:.9f},{alt:.4f},,,,,2.5,0")
    write_csv(line / "estimates" / "geo.csv", lines)
    report = evaluate(line, "geo")
    assert report["estimated_frames"] == len(lines)
    assert report["horizontal_error_m"]["max"] == pytest.approx(7.0, abs=0.01)
    assert report["latency_ms"] == {"median": 2.5, "p95": 2.5}
