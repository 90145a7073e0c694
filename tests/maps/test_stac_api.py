"""``air-sitl map fetch`` against a local STAC API, SAS token endpoint and blob store
(:mod:`tests.maps.stac_server`) serving small real COGs only with a valid token: signing, token
expiry and renewal, several acquisitions, dates in the files and in a flight's manifest,
resuming an interrupted download, and the one-line errors."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.warp import transform as warp_transform

from air_sitl.cli import _parser_for, build_parser, main
from air_sitl.errors import MapError
from air_sitl.maps import open_map
from air_sitl.maps.stac_http import default_sas_endpoint
from air_sitl.state import GeoPoint
from tests.maps.stac_server import (
    ACQUISITIONS,
    CRS,
    E0,
    GSD,
    N0,
    SIZE,
    StacServer,
    fetch_args,
)
from tests.short_plans import write_short_plan


def _resume() -> list[str]:
    """``--resume`` where ``map fetch`` has it (the overwrite rule), else nothing."""
    fetch = _parser_for(build_parser("map"), ["map", "fetch"])
    return ["--resume"] if "--resume" in fetch.format_help() else []


def _error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.startswith("air-sitl: error")]


def _tifs(out: Path) -> list[str]:
    return sorted(p.name for p in out.glob("*.tif*")) if out.exists() else []


def test_signed_fetch_writes_one_dated_cog_per_acquisition(
    server: StacServer, tmp_path: Path
) -> None:
    out = tmp_path / "naip"
    assert main(fetch_args(server, out)) == 0
    assert sorted(p.name for p in out.iterdir()) == [
        "fetch.json",
        *(f"naip_{d}.tif" for d, _ in ACQUISITIONS),
    ]
    for date, value in ACQUISITIONS:
        with rasterio.open(out / f"naip_{date}.tif") as src:
            tags = src.tags()
            row = src.read(1)[5]
            col0 = round((src.transform.c - E0) / GSD)
        assert tags["ACQUISITION_DATE"] == date
        assert tags["TIFFTAG_DATETIME"] == f"{date.replace('-', ':')} 17:05:00"
        # Pixels of both tiles, untouched: each tile's ramp where it lies.
        cols = np.arange(row.size) + col0
        expected = np.where(cols < SIZE, value + cols, value + 100 + cols - SIZE) % 256
        assert np.array_equal(row, expected.astype(np.uint8))
    record = json.loads((out / "fetch.json").read_text())
    assert record["outputs"]["naip_2014-07-02.tif"] == ["2014-a", "2014-b"]
    assert record["acquired"]["naip_2018-08-20.tif"] == "2018-08-20T17:05:00Z"
    assert server.state.hits["/api/sas/v1/token/naip"] == 1  # one token served the fetch
    assert server.state.hits["/api/stac/v1/search"] >= 3  # six items, two a page


def test_unsigned_asset_urls_are_refused_in_one_line(
    server: StacServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "naip"
    assert main(fetch_args(server, out, "--sas-endpoint", "none")) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "2010-a.tif (item 2010-a): HTTP 403, refused" in lines[0]
    assert "sig=" not in lines[0]
    assert _tifs(out) == [] and not (out / ".fetch-parts").exists()


def test_an_api_wanting_credentials_gets_them_on_every_request(
    server: StacServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    server.state.require = "Bearer s3cret"
    out = tmp_path / "naip"
    assert main(fetch_args(server, out)) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert (
        len(lines) == 1 and "HTTP 401 Unauthorized (refused: check --token / --header)" in lines[0]
    )
    assert main(fetch_args(server, out, "--token", "s3cret")) == 0  # search, token and assets
    assert len(_tifs(out)) == 3
    again = tmp_path / "again"
    assert main(fetch_args(server, again, "--header", "Authorization: Bearer s3cret")) == 0
    assert len(_tifs(again)) == 3


def test_planetary_computer_is_signed_by_default() -> None:
    pc = "https://planetarycomputer.microsoft.com/api/stac/v1"
    assert default_sas_endpoint(pc) == "https://planetarycomputer.microsoft.com/api/sas/v1/token"
    assert default_sas_endpoint("https://earth-search.aws.element84.com/v1") is None


def test_a_short_lived_token_is_asked_again_before_use(server: StacServer, tmp_path: Path) -> None:
    server.state.token_ttl_s = 30.0  # under the minute kept in hand: renewed for each asset
    assert main(fetch_args(server, tmp_path / "naip")) == 0
    assert server.state.hits["/api/sas/v1/token/naip"] == 6


def test_a_token_refused_early_is_renewed_once(server: StacServer, tmp_path: Path) -> None:
    server.state.revoke_after_assets = 1  # the token stops working in the first asset's read
    assert main(fetch_args(server, tmp_path / "naip")) == 0
    assert server.state.issued == 2
    assert len(_tifs(tmp_path / "naip")) == 3


def test_a_token_refused_again_after_renewal_is_reported(
    server: StacServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    server.state.refuse_assets = True
    assert main(fetch_args(server, tmp_path / "naip")) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1
    assert f"refused also with a token renewed from {server.base}/api/sas/v1/token/naip" in lines[0]
    assert server.state.issued == 2 and _tifs(tmp_path / "naip") == []


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"refuse_tokens": True}, "/api/sas/v1/token/naip: HTTP 403 Forbidden"),
        ({"dates": "1990-01-01/1999-12-31"}, "no naip item over --bbox"),
        ({"collection": "sentinel-2-l2a"}, "--collection sentinel-2-l2a: no such collection"),
        ({"bbox": "10,10,11,11"}, "--bbox 10,10,11,11: outside collection naip's extent"),
        ({"dates": "2010-13-01/2011-01-01"}, "--datetime '2010-13-01/2011-01-01': expected"),
        ({"header": "Authorization Bearer X"}, "--header 'Authorization Bearer X': expected"),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(
    server: StacServer,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    change: dict[str, object],
    expected: str,
) -> None:
    server.state.refuse_tokens = bool(change.get("refuse_tokens"))
    out = tmp_path / "naip"
    args = fetch_args(server, out, dates=str(change.get("dates", "2010-01-01/2022-12-31")))
    for key in ("collection", "bbox"):
        if key in change:
            args[args.index(f"--{key}") + 1] = str(change[key])
    if "header" in change:
        args += ["--header", str(change["header"])]
    assert main(args) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and expected in lines[0], lines
    assert _tifs(out) == []


def test_an_interrupted_download_resumes_where_it_stopped(
    server: StacServer,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("GDAL_HTTP_MAX_RETRY", "0")
    server.state.broken = {"/blob/naip/2014-b.tif"}
    out = tmp_path / "naip"
    assert main(fetch_args(server, out)) == 2
    lines = _error_lines(capsys.readouterr().err)
    assert len(lines) == 1 and "2014-b.tif (item 2014-b): the download stopped" in lines[0]
    assert "--resume continues where it stopped" in lines[0] and "sig=" not in lines[0]
    assert _tifs(out) == ["naip_2010-06-14.tif"]  # the date written, whole; nothing half
    assert [p.name for p in (out / ".fetch-parts" / "naip_2014-07-02").iterdir()] == ["2014-a.tif"]
    first = (out / "naip_2010-06-14.tif").read_bytes()
    server.state.broken.clear()
    server.state.hits.clear()
    assert main(fetch_args(server, out, *_resume())) == 0
    hits = server.state.hits
    assert [hits[f"/blob/naip/{i}.tif"] for i in ("2010-a", "2010-b", "2014-a")] == [0, 0, 0]
    assert hits["/blob/naip/2014-b.tif"] > 0 and hits["/blob/naip/2018-a.tif"] > 0
    assert (out / "naip_2010-06-14.tif").read_bytes() == first
    assert len(_tifs(out)) == 3 and not (out / ".fetch-parts").exists()


def test_map_dir_flies_by_date_and_the_manifest_names_it(
    server: StacServer, tmp_path: Path
) -> None:
    maps = tmp_path / "naip"
    assert main(fetch_args(server, maps)) == 0
    (maps / "undated.tif").write_bytes(b"not a tiff")  # skipped: no date
    lon, lat = warp_transform(CRS, "EPSG:4326", [E0 + 500], [N0 - 470])
    home = GeoPoint(lat_deg=lat[0], lon_deg=lon[0], alt_amsl_m=100.0)
    chosen = open_map(str(maps), home, date="2014-07-02")
    info = chosen.describe()
    chosen.close()  # type: ignore[attr-defined]
    assert info["date"] == "2014-07-02" and info["date_index"] == 1
    assert info["dates"] == [d for d, _ in ACQUISITIONS] and info["spec"] == str(maps)
    assert open_map(str(maps), home, date="2").describe()["date"] == "2018-08-20"
    with pytest.raises(MapError, match="--map-date 2030: no file has it"):
        open_map(str(maps), home, date="2030")
    plan = write_short_plan(tmp_path / "p.plan", home, leg_m=30.0, alt_m=120.0)
    out = tmp_path / "flight"
    args = ["fly", str(plan), "--air-start", "--quiet", "--out", str(out), "--map", str(maps)]
    assert main([*args, "--map-date", "2014-07-02", "--render-workers", "0"]) in (0, 1)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["map"]["date"] == "2014-07-02" and manifest["map"]["date_index"] == 1
    assert manifest["map"]["dates"] == [d for d, _ in ACQUISITIONS]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["map"] == {
        "date": "2014-07-02", "date_index": 1, "dates": [d for d, _ in ACQUISITIONS]
    }  # fmt: skip


def test_map_make_dates_its_geotiff(tmp_path: Path) -> None:
    out = tmp_path / "u.tif"
    args = ["map", "make", "urban", "--date", "2", "--size-m", "64", "64", "--out", str(out)]
    assert main(args) == 0
    with rasterio.open(out) as src:
        tags = src.tags()
    assert tags["ACQUISITION_DATE"] == "2016-04-22"
    assert tags["TIFFTAG_DATETIME"] == "2016:04:22 15:30:00"
    home = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=0.0)
    assert open_map(str(tmp_path), home).describe()["date"] == "2016-04-22"
