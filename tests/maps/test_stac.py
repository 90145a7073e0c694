"""``air-sitl map fetch`` offline: a static STAC catalog of small COGs the test writes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import rasterio
from rasterio.transform import Affine
from rasterio.warp import transform as warp_transform

from air_sitl.cli import main
from air_sitl.errors import MapError
from air_sitl.maps.stac import find_items, parse_bbox, parse_datetime

CRS = "EPSG:32615"  # St. Louis, where -90.2 W lies
E0, N0 = 730000.0, 4285000.0  # metres, a 1 m grid
SIZE = 64


def _cog(path: Path, x0: float, value: int, *, dtype: str = "uint8", count: int = 3) -> None:
    data = np.full((count, SIZE, SIZE), value, dtype=dtype)
    data[0, :, :] += np.arange(SIZE, dtype=dtype)[None, :]  # a ramp: copies show misplacement
    with rasterio.open(
        path, "w", driver="GTiff", width=SIZE, height=SIZE, count=count, dtype=dtype, crs=CRS,
        transform=Affine(1.0, 0.0, x0, 0.0, -1.0, N0),
    ) as dst:  # fmt: skip
        dst.write(data)


def _bbox_of(x0: float, x1: float, y0: float, y1: float) -> list[float]:
    lons, lats = warp_transform(CRS, "EPSG:4326", [x0, x1, x0, x1], [y0, y0, y1, y1])
    return [min(lons), min(lats), max(lons), max(lats)]


def _item(root: Path, coll: str, iid: str, date: str, x0: float, asset: str) -> str:
    data = {
        "type": "Feature", "stac_version": "1.0.0", "id": iid, "collection": coll,
        "bbox": _bbox_of(x0, x0 + SIZE, N0 - SIZE, N0),
        "geometry": None, "properties": {"datetime": f"{date}T16:00:00Z"},
        "assets": {asset: {"href": f"./{iid}.tif", "type": "image/tiff; application=geotiff"}},
        "links": [],
    }  # fmt: skip
    (root / coll / f"{iid}.json").write_text(json.dumps(data))
    return f"./{iid}.json"


@pytest.fixture
def catalog(tmp_path: Path) -> Path:
    root = tmp_path / "stac"
    links = []
    for coll, asset in (("naip", "image"), ("cop-dem-glo-30", "data")):
        (root / coll).mkdir(parents=True)
        items = []
        if coll == "naip":
            # Two tiles side by side on one grid (2020), one tile of another date (2022).
            tiles = [("a", "2020-06-01", E0, 10), ("b", "2020-06-01", E0 + SIZE, 100)]
            tiles.append(("c", "2022-07-01", E0, 50))
            for iid, date, x0, v in tiles:
                _cog(root / coll / f"{iid}.tif", x0, v)
                items.append(_item(root, coll, iid, date, x0, asset))
        else:
            _cog(root / coll / "dem.tif", E0, 0, dtype="float32", count=1)
            items.append(_item(root, coll, "dem", "2021-01-01", E0, asset))
        (root / coll / "collection.json").write_text(json.dumps({
            "type": "Collection", "id": coll, "links": [{"rel": "item", "href": i} for i in items],
        }))  # fmt: skip
        links.append({"rel": "child", "href": f"./{coll}/collection.json"})
    (root / "catalog.json").write_text(json.dumps({"type": "Catalog", "id": "t", "links": links}))
    return root / "catalog.json"


def test_fetch_mosaics_one_cog_per_date_without_resampling(
    catalog: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "maps"
    w, s, e, n = _bbox_of(E0 + 10, E0 + 110, N0 - 50, N0 - 10)
    bbox = f"{w},{s},{e},{n}"
    args = ["map", "fetch", "--bbox", bbox, "--collection", "naip", "--stac", str(catalog)]
    assert main([*args, "--datetime", "2020-01-01/2020-12-31", "--out", str(out)]) == 0
    with rasterio.open(out / "naip_2020-06-01.tif") as src:
        assert src.crs.to_string() == CRS and src.transform.a == 1.0
        data = src.read()
        col0 = round(src.transform.c - E0)
    # Pixels copied from both tiles, untouched: the ramp continues across the seam.
    first_band = data[0, 5]
    cols = np.arange(first_band.size) + col0
    expected = np.where(cols < SIZE, 10 + cols, 100 + cols - SIZE)
    assert np.array_equal(first_band, expected.astype(np.uint8))
    record = json.loads((out / "fetch.json").read_text())
    assert record["outputs"] == {"naip_2020-06-01.tif": ["a", "b"]}
    assert not (out / "naip_2022-07-01.tif").exists()
    # --resume: skipped; other dates into the same folder: refused, nothing changed, then
    # replaced with --overwrite; the DEM as dem.tif in a folder of its own.
    files = {p.name: p.read_bytes() for p in out.iterdir()}
    mtime = (out / "naip_2020-06-01.tif").stat().st_mtime_ns
    assert main([*args, "--datetime", "2020-01-01/2020-12-31", "--out", str(out), "--resume"]) == 0
    assert (out / "naip_2020-06-01.tif").stat().st_mtime_ns == mtime
    capsys.readouterr()
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "a fetch of other inputs: datetime differ" in err and "--resume" not in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == files
    assert main([*args, "--out", str(out), "--overwrite"]) == 0
    assert (out / "naip_2022-07-01.tif").exists()
    args[5] = "cop-dem-glo-30"
    assert main([*args, "--out", str(tmp_path / "dem")]) == 0
    assert (tmp_path / "dem" / "dem.tif").exists()


def test_boxes_dates_and_filters(catalog: Path) -> None:
    assert parse_bbox("-90.2,38.6,-90.1,38.7") == (-90.2, 38.6, -90.1, 38.7)
    with pytest.raises(MapError):
        parse_bbox("-90.1,38.6,-90.2,38.7")
    assert parse_datetime("2020-01-01/..") == ("2020-01-01", "9999-12-31")
    far = (10.0, 10.0, 11.0, 11.0)
    assert find_items(str(catalog), "ANY", far, parse_datetime(None)) == []
    w, s, e, n = _bbox_of(E0, E0 + 200, N0 - 60, N0)
    every = find_items(str(catalog), "ANY", (w, s, e, n), parse_datetime(None))
    assert {i.id for i in every} == {"a", "b", "c", "dem"}
