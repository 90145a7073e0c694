"""The command lines of docs/real-naip.md after ``map fetch``, over years fetched from the local
STAC API: bench two gaps over the folder (its leaderboard names the acquisition dates), then
match one year against the oldest with ``localize``."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rasterio.warp import transform as warp_transform

from air_sitl.cli import main
from air_sitl.state import GeoPoint
from tests.maps.stac_server import ACQUISITIONS, CRS, E0, N0, StacServer, fetch_args
from tests.short_plans import write_short_plan


@pytest.mark.integration
def test_fly_localize_and_bench_over_fetched_years(server: StacServer, tmp_path: Path) -> None:
    maps = tmp_path / "maps"
    assert main(fetch_args(server, maps)) == 0
    lon, lat = warp_transform(CRS, "EPSG:4326", [E0 + 500], [N0 - 470])
    home = GeoPoint(lat_deg=lat[0], lon_deg=lon[0], alt_amsl_m=290.0)
    missions = tmp_path / "farm-missions"
    missions.mkdir()
    write_short_plan(missions / "P-120.plan", home, leg_m=40.0, alt_m=120.0)
    # bench two gaps against the oldest year (it flies as `fly --map DIR --map-date N` does)
    bench = tmp_path / "bench-farm"
    argv = [
        "bench", "--missions", str(missions), "--scenarios", "P-120", "--map", str(maps),
        "--map-date", "0,2", "--reference-date", "0", "--methods", "mapmatch",
        "--out", str(bench), "--quiet",
    ]  # fmt: skip
    assert main(argv) in (0, 1)
    dates = [d for d, _ in ACQUISITIONS]
    md = (bench / "leaderboard.md").read_text()
    assert f"| method | {dates[0]} -> {dates[0]} | {dates[0]} -> {dates[2]} |" in md
    assert f"# reference date 0 ({dates[0]}) -> flight date 2 ({dates[2]})" in md
    data = json.loads((bench / "leaderboard.json").read_text())
    assert [g["map_dates"] for g in data["gaps"]] == [dates, dates]
    archive = bench / "date2" / "archives" / "P-120"
    manifest = json.loads((archive / "manifest.json").read_text())
    assert manifest["map"]["date"] == dates[2] and manifest["map"]["spec"] == str(maps)
    # match one year against the oldest: the reference is the flight's own map folder
    argv = ["localize", str(archive), "--method", "mapmatch", "--reference-date", "0"]
    assert main([*argv, "--name", "vs2010", "--quiet"]) == 0
    assert (archive / "estimates" / "vs2010.csv").is_file()
