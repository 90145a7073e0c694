"""``dataset``'s forecast (frames and bytes, before anything flies) against what it writes, on
a run cut by ``--max-sim-time``, over two map dates, with ``--zip``: within 20 %."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest
from short_plans import write_short_plan

from air_sitl.cli import main
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def test_forecast_is_within_a_fifth_of_what_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missions = tmp_path / "missions"
    missions.mkdir()
    # A 300 m capture leg (about 1000 frames) of which --max-sim-time keeps the first 3 s.
    write_short_plan(missions / "UC-200.plan", HOME, leg_m=300.0, leg="north")
    root = tmp_path / "air"
    argv = ["dataset", "--missions", str(missions), "--scenarios", "UC-200", "--air-start"]
    argv += ["--max-sim-time", "3", "--dates", "0,1", "--zip", "--out", str(root)]
    assert main(argv) == 1  # the time limit ended both missions
    line = capsys.readouterr().err.splitlines()[0]
    found = re.match(r"dataset: 2 recordings, about (\d+) frames to write: about ([\d.]+) MB", line)
    assert found, line
    frames = sum(
        json.loads((root / f"UC-200@{d}" / "manifest.json").read_text())["frame_count"]
        for d in (0, 1)
    )
    written = sum(p.stat().st_size for p in root.rglob("*") if p.is_file())
    assert 100 <= frames <= 400, frames  # cut short: the plan alone would be about 2000
    assert abs(int(found[1]) - frames) <= 0.2 * frames, (line, frames)
    assert abs(float(found[2]) * 1e6 - written) <= 0.2 * written, (line, written)
