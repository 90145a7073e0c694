"""A local STAC API and SAS token endpoint, as the services document them, for ``map fetch`` tests.

- STAC API (item search, stac-api-spec): ``GET {api}/collections/{id}`` (extent),
  ``POST {api}/search`` (``collections``, ``bbox``, ``datetime`` interval, ``limit``; pages
  through a ``next`` link with ``method: POST`` and ``body``) and ``GET {api}/search``.
- Planetary Computer's SAS endpoint: ``GET /api/sas/v1/token/{collection}`` ->
  ``{"msft:expiry": "<RFC 3339>", "token": "st=...&se=...&sp=rl&sig=..."}``.
- Blob storage: ``/blob/{collection}/{name}.tif?<token>``, ranged GET and HEAD, 403 without a
  valid token (as Azure answers an unsigned or expired SAS URL).

Every request is counted by path (``hits``); switches make the tokens expire early, refuse
them, or fail an asset (``broken``) as an interrupted download would.
"""

from __future__ import annotations

import collections
import contextlib
import json
import re
import threading
import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

import numpy as np
import rasterio
from rasterio.shutil import copy as rio_copy
from rasterio.transform import Affine
from rasterio.warp import transform as warp_transform

PAGE_SIZE = 2  # items per search page: a search of several dates pages


@dataclass
class StacState:
    """What the server holds and how it behaves (tests flip the switches)."""

    items: list[dict[str, Any]]
    files: dict[str, Path]  # blob path -> file
    extent: list[float]
    token_ttl_s: float = 3600.0
    refuse_tokens: bool = False  # the token endpoint answers 403
    revoke_after_assets: int | None = None  # tokens stop working after N asset requests
    refuse_assets: bool = False  # every token is refused by the blob store
    broken: set[str] = field(default_factory=set)  # blob paths answered 503
    require: str | None = None  # an Authorization header every request must carry (else 401)
    valid: set[str] = field(default_factory=set)
    hits: collections.Counter[str] = field(default_factory=collections.Counter)
    assets_served: int = 0
    issued: int = 0
    lock: threading.Lock = field(default_factory=threading.Lock)


def _overlaps(a: list[float], b: list[float]) -> bool:
    return not (a[2] <= b[0] or a[0] >= b[2] or a[3] <= b[1] or a[1] >= b[3])


def _in_interval(stamp: str, interval: str) -> bool:
    lo, _, hi = interval.partition("/")
    day = stamp[:10]
    return (lo in ("", "..") or day >= lo[:10]) and (hi in ("", "..") or day <= hi[:10])


class _Handler(BaseHTTPRequestHandler):
    state: StacState

    def log_message(self, format: str, *args: Any) -> None:
        return

    def _json(self, value: Any, status: int = 200) -> None:
        body = json.dumps(value).encode()
        self.send_response(status)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(body)))
        self.end_headers()
        self.wfile.write(body)

    def _search(self, query: dict[str, Any]) -> None:
        st = self.state
        found = [
            it
            for it in st.items
            if (not query.get("collections") or it["collection"] in query["collections"])
            and _overlaps(it["bbox"], query["bbox"])
            and _in_interval(it["properties"]["datetime"], query.get("datetime", ".."))
        ]
        start = int(query.get("next", 0))
        page = found[start : start + PAGE_SIZE]
        links = []
        if start + PAGE_SIZE < len(found):
            href = f"http://{self.headers['Host']}/api/stac/v1/search"
            nxt = {"next": start + PAGE_SIZE}
            links.append(
                {"rel": "next", "href": href, "method": "POST", "body": nxt, "merge": True}
            )
        self._json({"type": "FeatureCollection", "features": page, "links": links})

    def _unauthorized(self) -> bool:
        """401 for a request without the required Authorization header (True: answered)."""
        need = self.state.require
        if need is None or self.headers.get("Authorization") == need:
            return False
        self._json({"detail": "Unauthorized"}, 401)
        return True

    def do_POST(self) -> None:
        path = urllib.parse.urlparse(self.path).path
        self.state.hits[path] += 1
        if self._unauthorized():
            return
        body = json.loads(self.rfile.read(int(self.headers.get("Content-Length", 0))))
        if path == "/api/stac/v1/search":
            self._search(body)
        else:
            self._json({"detail": "not found"}, 404)

    def do_HEAD(self) -> None:
        if not self._unauthorized():
            self._blob(head=True)

    def do_GET(self) -> None:
        url = urllib.parse.urlparse(self.path)
        st = self.state
        with st.lock:
            st.hits[url.path] += 1
        if self._unauthorized():
            return
        if url.path.startswith("/blob/"):
            self._blob(head=False)
        elif url.path.startswith("/api/sas/v1/token/"):
            if st.refuse_tokens:
                self._json({"detail": "Forbidden"}, 403)
                return
            with st.lock:
                st.issued += 1
                sig = f"sig{st.issued}"
                st.valid.add(sig)
            expiry = datetime.now(UTC) + timedelta(seconds=st.token_ttl_s)
            stamp = expiry.strftime("%Y-%m-%dT%H:%M:%SZ")
            self._json({"msft:expiry": stamp, "token": f"se={stamp}&sp=rl&sv=2021-06-08&sig={sig}"})
        elif url.path == "/api/stac/v1/search":
            q = urllib.parse.parse_qs(url.query)
            query: dict[str, Any] = {"bbox": [float(v) for v in q["bbox"][0].split(",")]}
            query["datetime"] = q.get("datetime", [".."])[0]
            if "collections" in q:
                query["collections"] = q["collections"][0].split(",")
            self._search(query)
        elif url.path.startswith("/api/stac/v1/collections/"):
            cid = url.path.rsplit("/", 1)[1]
            if not any(it["collection"] == cid for it in st.items):
                self._json({"detail": "not found"}, 404)
                return
            self._json(
                {"type": "Collection", "id": cid, "extent": {"spatial": {"bbox": [st.extent]}}}
            )
        else:
            self._json({"detail": "not found"}, 404)

    def _blob(self, *, head: bool) -> None:
        st = self.state
        url = urllib.parse.urlparse(self.path)
        sig = urllib.parse.parse_qs(url.query).get("sig", [""])[0]
        with st.lock:
            ok = sig in st.valid and not st.refuse_assets
            if ok and not head:
                st.assets_served += 1
                if st.revoke_after_assets is not None and st.assets_served > st.revoke_after_assets:
                    st.valid.discard(sig)  # expired before its announced time
                    st.revoke_after_assets = None
                    ok = False
        if url.path not in st.files:
            self.send_error(404)
            return
        if not ok:
            self.send_response(403)  # Azure: AuthenticationFailed
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        if url.path in st.broken:
            self.send_response(503)
            self.send_header("Content-Length", "0")
            self.end_headers()
            return
        data = st.files[url.path].read_bytes()
        found = re.fullmatch(r"bytes=(\d+)-(\d*)", self.headers.get("Range", ""))
        if found:
            a = int(found.group(1))
            b = min(int(found.group(2) or len(data) - 1), len(data) - 1)
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {a}-{b}/{len(data)}")
            chunk = data[a : b + 1]
        else:
            self.send_response(200)
            chunk = data
        self.send_header("Accept-Ranges", "bytes")
        self.send_header("Content-Length", str(len(chunk)))
        self.send_header("Content-Type", "image/tiff")
        self.end_headers()
        if not head:
            self.wfile.write(chunk)


class StacServer:
    """The server on 127.0.0.1, port 0, in a thread (a context manager)."""

    def __init__(self, state: StacState) -> None:
        handler = type("Handler", (_Handler,), {"state": state})
        self.state = state
        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
        self.base = f"http://127.0.0.1:{self.httpd.server_address[1]}"
        # shutdown() waits for the loop's next poll: every 0.05 s, not the default 0.5 s (half
        # a second of wall at the end of each test).
        self.thread = threading.Thread(
            target=self.httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
        )

    def __enter__(self) -> StacServer:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()


# The fixture: six tiles (two per acquisition) on one UTM grid, behind the server.
CRS = "EPSG:32615"
E0, N0 = 730000.0, 4285000.0
GSD = 2.0
SIZE = 256  # px per tile: 512 m
ACQUISITIONS = (("2010-06-14", 10), ("2014-07-02", 60), ("2018-08-20", 110))
BBOX_M = (E0 + 50, N0 - 500, E0 + 1000, N0 - 10)  # across both tiles of each date


def _wgs84(xs: list[float], ys: list[float]) -> list[float]:
    lons, lats = warp_transform(CRS, "EPSG:4326", xs, ys)
    return [min(lons), min(lats), max(lons), max(lats)]


def _cog(path: Path, x0: float, value: int) -> None:
    data = np.zeros((3, SIZE, SIZE), dtype=np.uint8)
    data[:] = value
    data[0] = (value + np.arange(SIZE)[None, :]) % 256  # a ramp: a misplaced copy shows
    tmp = path.with_suffix(".src.tif")
    with rasterio.open(
        tmp, "w", driver="GTiff", width=SIZE, height=SIZE, count=3, dtype="uint8", crs=CRS,
        transform=Affine(GSD, 0.0, x0, 0.0, -GSD, N0),
    ) as dst:  # fmt: skip
        dst.write(data)
    rio_copy(tmp, path, driver="COG", COMPRESS="DEFLATE")
    tmp.unlink()


@contextlib.contextmanager
def serve_tiles(tmp_path: Path) -> Iterator[StacServer]:
    """The server of the tests, its blobs in ``tmp_path/blobs`` (tests' ``server`` fixture)."""
    blobs = tmp_path / "blobs"
    blobs.mkdir()
    items, files = [], {}
    for date, value in ACQUISITIONS:
        for tile, dx, dv in (("a", 0.0, 0), ("b", SIZE * GSD, 100)):
            iid = f"{date[:4]}-{tile}"
            _cog(blobs / f"{iid}.tif", E0 + dx, value + dv)
            x0 = E0 + dx
            files[f"/blob/naip/{iid}.tif"] = blobs / f"{iid}.tif"
            items.append({
                "type": "Feature", "stac_version": "1.0.0", "id": iid, "collection": "naip",
                "bbox": _wgs84([x0, x0 + SIZE * GSD], [N0 - SIZE * GSD, N0]), "geometry": None,
                "properties": {"datetime": f"{date}T17:05:00Z"}, "links": [],
                "assets": {"image": {"href": "", "type": "image/tiff; application=geotiff"}},
            })  # fmt: skip
    state = StacState(items=items, files=files, extent=_wgs84([E0, E0 + 1024], [N0 - 512, N0]))
    with StacServer(state) as srv:
        for it in items:
            it["assets"]["image"]["href"] = f"{srv.base}/blob/naip/{it['id']}.tif"
        yield srv


def fetch_args(
    srv: StacServer, out: Path, *extra: str, dates: str = "2010-01-01/2022-12-31"
) -> list[str]:
    w, s, e, n = _wgs84([BBOX_M[0], BBOX_M[2]], [BBOX_M[1], BBOX_M[3]])
    return [
        "map", "fetch", "--bbox", f"{w},{s},{e},{n}", "--collection", "naip",
        "--stac", f"{srv.base}/api/stac/v1", "--sas-endpoint", f"{srv.base}/api/sas/v1/token",
        "--datetime", dates, "--out", str(out), *extra,
    ]  # fmt: skip
