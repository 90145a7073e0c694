"""Real maps from STAC: find the items over a box and dates, mosaic their COG windows by date.

Two sources: a STAC API (its item search, ``POST {api}/search``, GET where POST is refused,
following ``next`` links) and a static catalog (a ``catalog.json`` / ``collection.json`` path or
URL: it has no search, so its children and items are walked and filtered by bbox and datetime
here). Requests carry ``--header`` / ``--token``; asset URLs are signed with a SAS token where
the source needs it (:mod:`air_sitl.maps.stac_http`). Pixels are read by window from the
assets (:mod:`air_sitl.maps.stac_raster`); one COG per acquisition date
(``<collection>_<YYYY-MM-DD>.tif``, dated by its tags; elevation collections: ``dem.tif``)
and ``fetch.json`` naming the items used, rewritten after each date. Each item's part is kept
under ``DIR/.fetch-parts/`` until its date is written, so an interrupted fetch resumes where it
stopped: dates written and parts read are not fetched again.
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import urllib.parse
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

from air_sitl.errors import MapError
from air_sitl.files import parse_json_object, write_json_atomic
from air_sitl.maps.stac_http import REFUSED, Http, HttpError, SasSigner, unsigned

PARTS_DIR = ".fetch-parts"  # items' parts of the dates not yet written
MAX_PAGES = 100  # of a search's results (NAIP over a farm: a page or two)
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
    time: str = "00:00:00"  # HH:MM:SS (UTC) of the acquisition, as the item says


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
    for day in (lo, hi):
        try:
            if day and day != "..":
                datetime.strptime(day, "%Y-%m-%d")
        except ValueError:
            msg = f"--datetime {text!r}: expected START/END as YYYY-MM-DD or .. (open)"
            raise MapError(msg) from None
    return (lo if lo and lo != ".." else "0000-01-01", hi if hi and hi != ".." else "9999-12-31")


def is_elevation(collection: str) -> bool:
    """Whether a collection holds heights (its mosaic is ``dem.tif``)."""
    name = collection.lower()
    return any(k in name for k in ELEVATION)


def _load(href: str, http: Http) -> dict[str, Any]:
    if urllib.parse.urlparse(href).scheme in ("http", "https"):
        return http.json(href, f"--stac {href}")
    try:
        data = Path(href).read_bytes()
    except OSError as err:
        msg = f"--stac {href}: cannot read it ({err.strerror or err})"
        raise MapError(msg) from None
    return parse_json_object(data, f"--stac {href}", MapError)


def _join(base: str, href: str) -> str:
    if urllib.parse.urlparse(href).scheme or Path(href).is_absolute():
        return href
    if urllib.parse.urlparse(base).scheme in ("http", "https"):
        return urllib.parse.urljoin(base, href)
    return str((Path(base).parent / href).resolve())


def _walk(
    href: str, collection: str | None, http: Http
) -> Iterator[tuple[dict[str, Any], str, str]]:
    """Items of a static catalog: (item JSON, its href, its collection id)."""
    data = _load(href, http)
    kind = data.get("type")
    if kind == "Feature":
        yield data, href, str(data.get("collection", collection or ""))
        return
    here = str(data["id"]) if kind == "Collection" else collection
    for link in data.get("links", []):
        rel = link.get("rel")
        if rel in ("child", "item"):
            yield from _walk(_join(href, str(link["href"])), here, http)


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
        time=_time_of(str(when)),
        bbox=(float(bbox[0]), float(bbox[1]), float(bbox[2]), float(bbox[3])),
        href=_join(href, asset),
    )


def _time_of(stamp: str) -> str:
    """``HH:MM:SS`` of an RFC 3339 stamp (midnight when it has no time)."""
    clock = stamp[11:19]
    return clock if len(clock) == 8 and clock[2] == clock[5] == ":" else "00:00:00"


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


def _bbox_text(bbox: BBox) -> str:
    return ",".join(f"{v:g}" for v in bbox)


def _rfc3339(when: tuple[str, str]) -> str:
    """The STAC API's ``datetime`` interval of two inclusive days (``..``: open)."""
    lo = ".." if when[0] == "0000-01-01" else f"{when[0]}T00:00:00Z"
    hi = ".." if when[1] == "9999-12-31" else f"{when[1]}T23:59:59Z"
    return f"{lo}/{hi}"


@dataclass(frozen=True, slots=True)
class Source:
    """Where a fetch reads from: a STAC API URL or a static catalog, with its requests."""

    stac: str
    http: Http = field(default_factory=Http)
    sas_endpoint: str | None = None  # a SAS token endpoint signing the asset URLs

    @property
    def is_catalog(self) -> bool:
        return self.stac.endswith(".json")


def find_items(
    source: Source | str, collection: str, bbox: BBox, when: tuple[str, str]
) -> list[StacItem]:
    """Items of ``collection`` ("ANY": every one) over ``bbox`` within the date range."""
    src = source if isinstance(source, Source) else Source(source)
    found: list[StacItem] = []
    if src.is_catalog:
        for data, href, coll in _walk(src.stac, None, src.http):
            if collection.upper() != "ANY" and coll != collection:
                continue
            item = _item(data, href, coll)
            if item and _overlaps(item.bbox, bbox) and when[0] <= item.date <= when[1]:
                found.append(item)
    else:
        _check_extent(src, collection, bbox)
        found = _search_api(src, collection, bbox, when)
    return sorted(found, key=lambda i: (i.date, i.id))


def _check_extent(src: Source, collection: str, bbox: BBox) -> None:
    """A collection the API does not have, or a box outside its extent: said before searching."""
    if collection.upper() == "ANY":
        return
    url = f"{src.stac.rstrip('/')}/collections/{urllib.parse.quote(collection, safe='')}"
    try:
        data = src.http.json(url, f"--collection {collection}")
    except HttpError as err:
        if err.status == 404:
            msg = f"--collection {collection}: no such collection at --stac {src.stac}"
            raise MapError(msg) from None
        raise
    boxes = (data.get("extent") or {}).get("spatial", {}).get("bbox") or []
    extents = [tuple(float(v) for v in b[:2] + b[-2:]) for b in boxes if len(b) in (4, 6)]
    if extents and not any(_overlaps(bbox, e) for e in extents):  # type: ignore[arg-type]
        msg = (
            f"--bbox {_bbox_text(bbox)}: outside collection {collection}'s extent "
            f"({'; '.join(_bbox_text(e) for e in extents)})"  # type: ignore[arg-type]
        )
        raise MapError(msg)


def _search_api(src: Source, collection: str, bbox: BBox, when: tuple[str, str]) -> list[StacItem]:
    """Every item of an API's item search (POST; GET where the API refuses POST)."""
    url = f"{src.stac.rstrip('/')}/search"
    body: dict[str, Any] = {"bbox": list(bbox), "datetime": _rfc3339(when), "limit": 100}
    if collection.upper() != "ANY":
        body["collections"] = [collection]
    what = f"--stac {src.stac} (item search)"
    try:
        page = src.http.json(url, what, body)
    except HttpError as err:
        if err.status not in (404, 405):
            raise
        query = {k: ",".join(map(str, v)) if isinstance(v, list) else v for k, v in body.items()}
        page = src.http.json(f"{url}?{urllib.parse.urlencode(query)}", what)
    out: list[StacItem] = []
    for _ in range(MAX_PAGES):
        for feature in page.get("features") or []:
            coll = str(feature.get("collection") or collection)
            item = _item(feature, url, coll)
            if item:
                out.append(item)
        nxt = next((ln for ln in page.get("links") or [] if ln.get("rel") == "next"), None)
        if nxt is None or not page.get("features"):
            break
        if str(nxt.get("method", "GET")).upper() == "POST":
            next_body = (
                ({**body, **nxt["body"]} if nxt.get("merge") else nxt["body"])
                if nxt.get("body")
                else body
            )
            page = src.http.json(str(nxt["href"]), what, next_body)
        else:
            page = src.http.json(str(nxt["href"]), what)
    return out


def _output_name(item: StacItem) -> str:
    return "dem.tif" if is_elevation(item.collection) else f"{item.collection}_{item.date}.tif"


def resume_problem(out_dir: Path, inputs: dict[str, object]) -> str | None:
    """None when ``out_dir`` holds a fetch of ``inputs`` (``fetch.json``'s stac, collection,
    bbox and datetime: ``--resume`` continues it), else why not (:mod:`air_sitl.outdir`).
    A folder holding only the parts of a first date that was interrupted resumes too."""
    record_path = out_dir / "fetch.json"
    if not record_path.exists() and [p.name for p in out_dir.iterdir()] == [PARTS_DIR]:
        return None
    try:
        record = json.loads(record_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return "not a map fetch folder: no readable fetch.json"
    if not isinstance(record, dict):
        return "not a map fetch folder: fetch.json is not an object"
    diff = [k for k, v in inputs.items() if record.get(k) != v]
    return f"a fetch of other inputs: {', '.join(diff)} differ" if diff else None


@dataclass
class _Fetch:
    """One ``map fetch`` under way: its source, box, output folder and record."""

    source: Source
    bbox: BBox
    out_dir: Path
    record: dict[str, Any]
    signer: SasSigner | None = None

    @property
    def parts_dir(self) -> Path:
        return self.out_dir / PARTS_DIR

    def write_record(self) -> None:
        write_json_atomic(self.out_dir / "fetch.json", self.record)

    def part(self, name: str, item: StacItem) -> Path | None:
        """The item's part over the box (read now, or kept from an interrupted fetch);
        None when the asset does not reach into the box."""
        from air_sitl.maps.stac_raster import AssetReadError, read_asset_window

        folder = self.parts_dir / name.removesuffix(".tif")
        safe = "".join(c if c.isalnum() or c in "-_." else "_" for c in item.id)
        path, none = folder / f"{safe}.tif", folder / f"{safe}.none"
        if path.exists() or none.exists():
            return path if path.exists() else None
        folder.mkdir(parents=True, exist_ok=True)
        for attempt in (0, 1):
            href = item.href
            if self.signer is not None:
                href = self.signer.sign(item.href, item.collection)
            try:
                if read_asset_window(href, self.bbox, path, self.source.http.gdal_options()):
                    return path
                none.touch()
                return None
            except AssetReadError as err:
                status = err.status
                if status is None and urllib.parse.urlparse(href).scheme in ("http", "https"):
                    status = self.source.http.status(href)  # GDAL does not always say
                    status = None if status == 200 else status
                if status in REFUSED and attempt == 0 and self.signer is not None:
                    self.signer.renew(item.collection)  # expired or revoked early: once more
                    continue
                raise MapError(self._failure(item, status, str(err))) from None
        raise AssertionError("unreachable")

    def _failure(self, item: StacItem, status: int | None, detail: str) -> str:
        asset = f"{unsigned(item.href)} (item {item.id})"
        if status in REFUSED and self.signer is not None:
            url = self.signer.token_url(item.collection)
            return f"{asset}: HTTP {status}, refused also with a token renewed from {url}"
        if status in REFUSED:
            hint = "" if self.source.http.headers else "; does it need --token or --header?"
            return f"{asset}: HTTP {status}, refused{hint}"
        done = len(self.record["outputs"])
        why = f"HTTP {status}" if status else (detail.strip().splitlines() or ["no answer"])[-1]
        why = re.sub(r"(https?://[^\s'\"?]+)\?[^\s'\"]*", r"\1", why)  # never the token
        return (
            f"{asset}: the download stopped ({why}); {done} file(s) written to "
            f"{self.out_dir}: the same command with --resume continues where it stopped"
        )


def fetch(
    source: Source | str,
    collection: str,
    bbox: BBox,
    when: tuple[str, str],
    out_dir: Path,
) -> dict[str, Any]:
    """Write one dated COG per acquisition date (or dem.tif) and fetch.json; dates written
    and items' parts read before are not fetched again."""
    from air_sitl.maps.geotiff import date_tags  # rasterio only here
    from air_sitl.maps.stac_raster import mosaic_cog

    src = source if isinstance(source, Source) else Source(source)
    items = find_items(src, collection, bbox, when)
    if not items:
        msg = (
            f"--stac {src.stac}: no {collection} item over --bbox {_bbox_text(bbox)} between "
            f"{when[0]} and {when[1]}"
        )
        raise MapError(msg)
    record_path = out_dir / "fetch.json"
    record: dict[str, Any] = (
        parse_json_object(record_path.read_bytes(), str(record_path), MapError)
        if record_path.exists()
        else {}
    )
    record.setdefault("outputs", {})
    record.setdefault("acquired", {})
    record.update(
        {
            "stac": src.stac,
            "collection": collection,
            "bbox": list(bbox),
            "datetime": f"{when[0]}/{when[1]}",
        }
    )
    signer = SasSigner(src.sas_endpoint, src.http) if src.sas_endpoint else None
    job = _Fetch(source=src, bbox=bbox, out_dir=out_dir, record=record, signer=signer)
    groups: dict[str, list[StacItem]] = {}
    for item in items:
        groups.setdefault(_output_name(item), []).append(item)
    created = not out_dir.exists()
    try:
        _fetch_groups(job, groups, date_tags, mosaic_cog)
    finally:  # what an error leaves: the dates written, the parts read; no empty folder
        for folder in sorted(job.parts_dir.glob("*"), reverse=True):
            if folder.is_dir() and not any(folder.iterdir()):
                folder.rmdir()
        if job.parts_dir.is_dir() and not any(job.parts_dir.iterdir()):
            job.parts_dir.rmdir()
        if created and out_dir.is_dir() and not any(out_dir.iterdir()):
            out_dir.rmdir()
    if not record["outputs"]:
        msg = f"--bbox {_bbox_text(bbox)}: the {len(items)} item(s) found have no pixels over it"
        raise MapError(msg)
    job.write_record()
    return record


def _fetch_groups(
    job: _Fetch,
    groups: dict[str, list[StacItem]],
    date_tags: Callable[[str, str], dict[str, str]],
    mosaic_cog: Callable[[list[Path], BBox, Path, dict[str, str]], None],
) -> None:
    """Each output file in turn: its items' parts, then the dated mosaic and the record."""
    record, bbox, out_dir = job.record, job.bbox, job.out_dir
    for k, (name, group) in enumerate(sorted(groups.items()), 1):
        target = out_dir / name
        bar = f"[{'#' * k}{'.' * (len(groups) - k)}] {k}/{len(groups)} {name}"
        if target.exists() and record["outputs"].get(name) is not None:
            print(f"air-sitl map fetch: {bar} (done before)", file=sys.stderr, flush=True)
            continue
        print(f"air-sitl map fetch: {bar}", file=sys.stderr, flush=True)
        parts = [(item, p) for item in group if (p := job.part(name, item)) is not None]
        if not parts:
            print(f"air-sitl map fetch: {name}: no pixels over the box", file=sys.stderr)
            shutil.rmtree(job.parts_dir / name.removesuffix(".tif"), ignore_errors=True)
            continue
        first = parts[0][0]
        tags = {} if name == "dem.tif" else date_tags(first.date, first.time)
        mosaic_cog([p for _, p in parts], bbox, target, tags)
        record["outputs"][name] = [item.id for item, _ in parts]
        if tags:
            record["acquired"][name] = f"{first.date}T{first.time}Z"
        record["fetched_at"] = datetime.now().astimezone().isoformat(timespec="seconds")
        job.write_record()
        shutil.rmtree(job.parts_dir / name.removesuffix(".tif"), ignore_errors=True)
