"""Real maps from STAC: find the items over a box and dates, mosaic their COG windows by date.

Two sources: a STAC API (its search, through pystac-client, imported only then) and a static
catalog (a ``catalog.json`` / ``collection.json`` path or URL: it has no search, so its
children and items are walked and filtered by bbox and datetime here). Pixels are read by
window from the assets (rasterio, in :mod:`air_sitl.maps.geotiff`); one COG per date
(``<collection>_<YYYY-MM-DD>.tif``; elevation collections: ``dem.tif``) and ``fetch.json``
naming the items used. Running again into the same folder skips the files already written.
"""

from __future__ import annotations

import json
import sys
import urllib.parse
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from air_sitl.errors import MapError
from air_sitl.files import parse_json_object

ELEVATION = ("3dep", "cop-dem", "dem", "srtm", "nasadem", "elevation")
BBox = tuple[float, float, float, float]


@dataclass(frozen=True, slots=True)
class StacItem:
    """What a fetch needs of one item: id, collection, date, footprint, the raster asset."""

    id: str
    collection: str
    date: str  # YYYY-MM-DD
    bbox: BBox
    href: str


def parse_bbox(text: str) -> BBox:
    """``W,S,E,N`` in degrees (western longitudes negative, as typed)."""
    try:
        w, s, e, n = (float(v) for v in text.split(","))
    except ValueError:
        msg = f"--bbox {text!r}: expected W,S,E,N in degrees (e.g. -90.2,38.6,-90.1,38.7)"
        raise MapError(msg) from None
    if not (-180 <= w < e <= 180 and -90 <= s < n <= 90):
        msg = f"--bbox {text!r}: expected W < E in [-180, 180] and S < N in [-90, 90]"
        raise MapError(msg)
    return (w, s, e, n)


def parse_datetime(text: str | None) -> tuple[str, str]:
    """``START/END`` (ISO dates or ``..``) as an inclusive range of YYYY-MM-DD strings."""
    if not text:
        return ("0000-01-01", "9999-12-31")
    parts = text.split("/")
    if len(parts) == 1:
        parts = [parts[0], parts[0]]
    lo, hi = (p.strip()[:10] for p in parts[:2])
    return (lo if lo and lo != ".." else "0000-01-01", hi if hi and hi != ".." else "9999-12-31")


def is_elevation(collection: str) -> bool:
    """Whether a collection holds heights (its mosaic is ``dem.tif``)."""
    name = collection.lower()
    return any(k in name for k in ELEVATION)


def _load(href: str) -> dict[str, Any]:
    try:
        if urllib.parse.urlparse(href).scheme in ("http", "https"):
            with urllib.request.urlopen(href, timeout=60) as resp:
                data = resp.read()
        else:
            data = Path(href).read_bytes()
    except OSError as err:
        msg = f"--stac {href}: cannot read it ({err})"
        raise MapError(msg) from None
    return parse_json_object(data, f"--stac {href}", MapError)


def _join(base: str, href: str) -> str:
    if urllib.parse.urlparse(href).scheme or Path(href).is_absolute():
        return href
    if urllib.parse.urlparse(base).scheme in ("http", "https"):
        return urllib.parse.urljoin(base, href)
    return str((Path(base).parent / href).resolve())


def _walk(href: str, collection: str | None) -> Iterator[tuple[dict[str, Any], str, str]]:
    """Items of a static catalog: (item JSON, its href, its collection id)."""
    data = _load(href)
    kind = data.get("type")
    if kind == "Feature":
        yield data, href, str(data.get("collection", collection or ""))
        return
    here = str(data["id"]) if kind == "Collection" else collection
    for link in data.get("links", []):
        rel = link.get("rel")
        if rel in ("child", "item"):
            yield from _walk(_join(href, str(link["href"])), here)


def _item(data: dict[str, Any], href: str, collection: str) -> StacItem | None:
    props = data.get("properties", {})
    when = props.get("datetime") or props.get("start_datetime")
    bbox = data.get("bbox")
    asset = _raster_asset(data.get("assets", {}))
    if not when or not bbox or asset is None:
        return None
    return StacItem(
        id=str(data.get("id")),
        collection=collection,
        date=str(when)[:10],
        bbox=(float(bbox[0]), float(bbox[1]), float(bbox[2]), float(bbox[3])),
        href=_join(href, asset),
    )


def _raster_asset(assets: dict[str, Any]) -> str | None:
    """The href of the item's main raster: 'image' (NAIP), 'data' (DEMs), else a GeoTIFF."""
    for key in ("image", "data", "visual", "elevation"):
        if key in assets:
            return str(assets[key]["href"])
    for a in assets.values():
        if "tiff" in str(a.get("type", "")).lower() or str(a.get("href", "")).endswith(".tif"):
            return str(a["href"])
    return None


def _overlaps(a: BBox, b: BBox) -> bool:
    return not (a[2] <= b[0] or a[0] >= b[2] or a[3] <= b[1] or a[1] >= b[3])


def find_items(stac: str, collection: str, bbox: BBox, when: tuple[str, str]) -> list[StacItem]:
    """Items of ``collection`` ("ANY": every one) over ``bbox`` within the date range."""
    found: list[StacItem] = []
    if stac.endswith(".json"):
        for data, href, coll in _walk(stac, None):
            if collection.upper() != "ANY" and coll != collection:
                continue
            item = _item(data, href, coll)
            if item and _overlaps(item.bbox, bbox) and when[0] <= item.date <= when[1]:
                found.append(item)
    else:
        found = _search_api(stac, collection, bbox, when)
    return sorted(found, key=lambda i: (i.date, i.id))


def _search_api(url: str, collection: str, bbox: BBox, when: tuple[str, str]) -> list[StacItem]:
    try:
        from pystac_client import Client  # type: ignore[import-not-found, unused-ignore]
    except ImportError:
        msg = f"--stac {url}: searching a STAC API needs pystac-client (pip install pystac-client)"
        raise MapError(msg) from None
    search = Client.open(url).search(
        collections=None if collection.upper() == "ANY" else [collection],
        bbox=list(bbox),
        datetime=f"{when[0]}/{when[1]}",
    )
    out = []
    for it in search.items():
        item = _item(it.to_dict(), url, str(it.collection_id))
        if item:
            out.append(item)
    return out


def resume_problem(out_dir: Path, inputs: dict[str, object]) -> str | None:
    """None when ``out_dir`` holds a fetch of ``inputs`` (``fetch.json``'s stac, collection,
    bbox and datetime: ``--resume`` continues it), else why not (:mod:`air_sitl.outdir`)."""
    try:
        record = json.loads((out_dir / "fetch.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "not a map fetch folder: no readable fetch.json"
    if not isinstance(record, dict):
        return "not a map fetch folder: fetch.json is not an object"
    diff = [k for k, v in inputs.items() if record.get(k) != v]
    return f"a fetch of other inputs: {', '.join(diff)} differ" if diff else None


def fetch(
    stac: str, collection: str, bbox: BBox, when: tuple[str, str], out_dir: Path
) -> dict[str, Any]:
    """Write one COG per date (or dem.tif) and fetch.json; skip files already done."""
    from air_sitl.maps.geotiff import mosaic_cog  # rasterio only here

    items = find_items(stac, collection, bbox, when)
    if not items:
        msg = f"--stac {stac}: no {collection} item over {bbox} between {when[0]} and {when[1]}"
        raise MapError(msg)
    out_dir.mkdir(parents=True, exist_ok=True)
    record_path = out_dir / "fetch.json"
    record: dict[str, Any] = (
        json.loads(record_path.read_text()) if record_path.exists() else {"outputs": {}}
    )
    groups: dict[str, list[StacItem]] = {}
    for item in items:
        name = "dem.tif" if is_elevation(item.collection) else f"{item.collection}_{item.date}.tif"
        groups.setdefault(name, []).append(item)
    for k, (name, group) in enumerate(sorted(groups.items()), 1):
        target = out_dir / name
        done = record["outputs"].get(name)
        bar = f"[{'#' * k}{'.' * (len(groups) - k)}] {k}/{len(groups)} {name}"
        if target.exists() and done is not None:
            print(f"air-sitl map fetch: {bar} (done before)", file=sys.stderr, flush=True)
            continue
        print(f"air-sitl map fetch: {bar}", file=sys.stderr, flush=True)
        mosaic_cog([i.href for i in group], bbox, target)
        record["outputs"][name] = [i.id for i in group]
    record.update(
        {
            "stac": stac,
            "collection": collection,
            "bbox": list(bbox),
            "datetime": f"{when[0]}/{when[1]}",
            "fetched_at": datetime.now().astimezone().isoformat(timespec="seconds"),
        }
    )
    record_path.write_text(json.dumps(record, indent=2) + "\n")
    return record
