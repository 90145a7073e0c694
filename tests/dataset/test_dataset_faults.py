"""``dataset`` against what the disk holds: ROOT/<scenario> a file, ROOT read-only."""

from __future__ import annotations

from pathlib import Path

import pytest
from cli_errors import one_line_error
from short_plans import write_short_plan
from tmpfs import tmpfs

from air_sitl.cli import main
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


@pytest.fixture(scope="module")
def missions(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("missions")
    write_short_plan(folder / "UC-200.plan", HOME, leg_m=20.0, leg="north")
    return folder


def test_a_file_where_the_scenario_folder_goes_is_one_line(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = tmp_path / "root"
    root.mkdir()
    (root / "UC-200").write_text("mine\n")
    argv = ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--out", str(root)]
    line = one_line_error(argv, capsys)
    assert f"{root / 'UC-200'}: exists and is not a folder" in line
    assert (root / "UC-200").read_text() == "mine\n"  # nothing of the user's lost
    line = one_line_error([*argv, "--resume"], capsys)
    assert "is not a folder" in line


def test_a_read_only_root_is_refused_before_flying_and_claims_no_table(
    missions: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    with tmpfs(tmp_path / "ro", read_only=True) as root:
        argv = ["dataset", "--missions", str(missions), "--scenarios", "UC-200"]
        assert main([*argv, "--air-start", "--out", str(root)]) == 2
        out = capsys.readouterr()
        assert out.err == (
            f"air-sitl: error: {root}: cannot write in the output folder: Read-only file system\n"
        )
        assert "stats.csv" not in out.out
        assert list(root.iterdir()) == []
