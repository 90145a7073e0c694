"""GeoTIFF / Cloud-Optimized GeoTIFF maps read by window with rasterio (its only importer).

The file's overviews serve as the pyramid where their factor is 2**L; missing levels are built
in memory from the finer level, tile by tile, so any file flies with bounded memory (a large
file without overviews is slow at high altitude, not big). Any CRS GDAL knows works: UTM
fast (pure maths), others through GDAL's transform, geographic CRSs included.
"""

from __future__ import annotations

import math
import os
import re
import threading
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

# Decoded tiles are cached by the map itself (bounded LRU); GDAL's own block cache would
# otherwise grow to 5% of RAM on big files. Must be set before GDAL's first read.
os.environ.setdefault("GDAL_CACHEMAX", "64")

import rasterio  # after GDAL_CACHEMAX on purpose
from rasterio.enums import MaskFlags
from rasterio.errors import NotGeoreferencedWarning, RasterioError
from rasterio.shutil import copy as rio_copy
from rasterio.transform import Affine
from rasterio.warp import transform as warp_transform
from rasterio.windows import Window

from air_sitl.files import sha256_file
from air_sitl.maps.array import num_levels_for, utm_zone_of_crs
from air_sitl.maps.base import (
    DEFAULT_CACHE_BYTES,
    FILL_BGRX,
    TILE_PX,
    Georeference,
    Image,
    MapSource,
    TiledMap,
    map_error,
)
from air_sitl.maps.surface import TiledSurface
from air_sitl.maps.utm import latlon2utm

_METRES_PER_DEGREE = 111_319.49
ACQUISITION_DATE = "ACQUISITION_DATE"  # GDAL metadata item: YYYY-MM-DD of the imagery


def date_tags(date: str, time_hms: str = "00:00:00") -> dict[str, str]:
    """The tags that date a GeoTIFF: TIFFTAG_DATETIME (``YYYY:MM:DD HH:MM:SS``, TIFF's form)
    and ``ACQUISITION_DATE=YYYY-MM-DD``."""
    return {"TIFFTAG_DATETIME": f"{date.replace('-', ':')} {time_hms}", ACQUISITION_DATE: date}


def _date_of(tags: dict[str, str]) -> str | None:
    """ACQUISITION_DATE, else the date of TIFFTAG_DATETIME, as YYYY-MM-DD (None: undated)."""
    found = re.fullmatch(r"\d{4}-\d{2}-\d{2}", tags.get(ACQUISITION_DATE, "").strip())
    if found:
        return found.group(0)
    stamp = re.match(r"(\d{4})[:-](\d{2})[:-](\d{2})", tags.get("TIFFTAG_DATETIME", "").strip())
    return "-".join(stamp.groups()) if stamp else None


def read_acquisition_date(path: Path) -> str | None:
    """The acquisition date a GeoTIFF carries (None: no date tag, or not a readable TIFF)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            with rasterio.open(path) as src:
                return _date_of(src.tags())
    except RasterioError:
        return None


def _open_georeferenced(path: Path, option: str) -> Any:
    """``path`` opened by rasterio, with a CRS and a geotransform; else a one-line MapError
    naming the file (after ``option``, e.g. ``"--dem: "``)."""
    if not path.is_file():
        raise map_error(str(path), f"{option}no such GeoTIFF file")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            src = rasterio.open(path)
    except RasterioError as err:
        raise map_error(str(path), f"{option}not a readable GeoTIFF ({err})") from None
    if src.crs is None or src.transform.is_identity:
        src.close()
        raise map_error(str(path), f"{option}not georeferenced (no CRS or no geotransform)")
    return src


class _GeoTiffFile:
    """A georeferenced GeoTIFF that several threads read: its path, handle, lock and hash."""

    path: Path
    name: str
    _src: Any
    _lock: threading.Lock
    _sha256: str | None

    def _open_file(self, path: Path, option: str) -> Any:
        """Open ``path`` for reading (:func:`_open_georeferenced`); return the handle."""
        self.path = path
        self.name = path.name
        self._src = _open_georeferenced(path, option)
        self._lock = threading.Lock()
        self._sha256 = None
        return self._src

    def _provenance(self, source: str, crs: str) -> dict[str, Any]:
        """Where the map or relief came from, as the manifest records it (SHA-256 once)."""
        if self._sha256 is None:
            self._sha256 = sha256_file(self.path)
        return {"source": source, "path": str(self.path), "sha256": self._sha256, "crs": crs}


class GeoTiffMap(TiledMap, _GeoTiffFile):
    """One georeferenced RGB/gray uint8 TIFF; windowed reads only."""

    def __init__(
        self,
        path: Path,
        *,
        ground_elevation_m: float,
        cache_bytes: int = DEFAULT_CACHE_BYTES,
    ) -> None:
        super().__init__(cache_bytes)
        src = self._open_file(path, "")
        self._overviews: dict[int, Any] = {}
        if src.count not in (1, 3, 4) or any(dt != "uint8" for dt in src.dtypes):
            src.close()
            msg = f"{src.count} band(s) of {src.dtypes[0]}: expected 1, 3 or 4 bands of uint8"
            raise map_error(str(path), msg)
        t = src.transform
        affine = (t.c, t.a, t.b, t.f, t.d, t.e)
        det = abs(t.a * t.e - t.b * t.d)
        self._geographic = bool(src.crs.is_geographic)
        crs_text = src.crs.to_string()
        self._zone = utm_zone_of_crs(crs_text)
        if self._geographic:
            lat_mid = t.f + t.e * src.height / 2.0
            gsd = math.sqrt(det * math.cos(math.radians(lat_mid))) * _METRES_PER_DEGREE
        else:
            gsd = math.sqrt(det) * float(src.crs.linear_units_factor[1])
        self.georef = Georeference(
            crs=crs_text, transform=affine, width_px=src.width, height_px=src.height, gsd_m=gsd
        )
        self.ground_elevation_m = ground_elevation_m
        self.num_levels = num_levels_for(src.width, src.height)
        self._overview_index = {
            round(math.log2(f)): i for i, f in enumerate(src.overviews(1)) if f & (f - 1) == 0
        }
        self._crs_text = crs_text
        self.acquisition_date = _date_of(src.tags())  # YYYY-MM-DD, None when undated
        self.date_index: int | None = None  # its place among the map's dates (maps.open sets it)
        self.dates: tuple[str | None, ...] = (self.acquisition_date,)  # every date of the map
        self.spec: str | None = None  # the --map value it was opened from
        # Nodata value, alpha band or mask: such pixels get alpha 0 (as off the map).
        self._masked = any(flags != [MaskFlags.all_valid] for flags in src.mask_flag_enums)

    def _latlon_to_crs(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        if self._zone is not None:
            return latlon2utm(lat_deg, lon_deg, self._zone)
        if self._geographic:
            return (lon_deg, lat_deg)
        xs, ys = warp_transform("EPSG:4326", self._crs_text, [lon_deg], [lat_deg])
        return (float(xs[0]), float(ys[0]))

    def _read(self, src: Any, x0: int, y0: int) -> Image:
        """A TILE_PX square at (x0, y0) of ``src`` as BGRx, filled outside the raster."""
        tile = np.empty((TILE_PX, TILE_PX, 4), dtype=np.uint8)
        tile[:] = FILL_BGRX
        w = min(TILE_PX, src.width - x0)
        h = min(TILE_PX, src.height - y0)
        if w <= 0 or h <= 0:
            return tile
        with self._lock:
            data = src.read(window=Window(x0, y0, w, h))
        if data.shape[0] == 1:
            tile[:h, :w, 0] = tile[:h, :w, 1] = tile[:h, :w, 2] = data[0]
        else:
            tile[:h, :w, 0] = data[2]
            tile[:h, :w, 1] = data[1]
            tile[:h, :w, 2] = data[0]
        if self._masked:
            with self._lock:
                tile[:h, :w, 3] = src.dataset_mask(window=Window(x0, y0, w, h))
        else:
            tile[:h, :w, 3] = 255
        return tile

    def _make_tile(self, tx: int, ty: int) -> Image:
        with self._lock:
            if self._src.closed:  # closed by a finished camera bridge, used again: reopen
                self._src = rasterio.open(self.path)
        return self._read(self._src, tx * TILE_PX, ty * TILE_PX)

    def _native_tile(self, level: int, tx: int, ty: int) -> Image | None:
        index = self._overview_index.get(level)
        if index is None:
            return None
        with self._lock:
            ovr = self._overviews.get(level)
            if ovr is None:
                ovr = rasterio.open(self.path, overview_level=index)
                self._overviews[level] = ovr
        return self._read(ovr, tx * TILE_PX, ty * TILE_PX)

    def describe(self) -> dict[str, Any]:
        """Provenance: file name, SHA-256 (computed once), CRS, size and dates: ``date`` its
        acquisition date (YYYY-MM-DD, null when undated), ``date_index`` its place among the
        map's ``dates`` (every file's, in order) and ``spec`` the --map value."""
        size_px = [self.georef.width_px, self.georef.height_px]
        provenance = self._provenance("geotiff", self._crs_text)
        dates: dict[str, Any] = {"date": self.acquisition_date, "date_index": self.date_index}
        if self.spec is not None:
            dates |= {"dates": list(self.dates), "spec": self.spec}
        return {**provenance, "size_px": size_px, "gsd_m": self.georef.gsd_m, **dates}

    def close(self) -> None:
        """Close the file and its overview handles."""
        with self._lock:
            for ovr in self._overviews.values():
                ovr.close()
            self._overviews.clear()
            self._src.close()


def write_geotiff(
    path: Path,
    tiles: Callable[[int, int, int, int], Image],
    *,
    width_px: int,
    height_px: int,
    crs: str,
    transform: tuple[float, float, float, float, float, float],
    jpeg_quality: int = 90,
    lossless: bool = False,
    tags: dict[str, str] | None = None,
) -> None:
    """Write a Cloud-Optimized GeoTIFF (tiled, JPEG q90 or DEFLATE, overviews) from blocks.

    ``tiles`` is a callable ``(x0, y0, w, h) -> (h, w, 3) BGR uint8`` giving level-0 pixels;
    the file is assembled block by block in a temporary tiled GeoTIFF (bounded memory), then
    copied by GDAL's COG driver, which builds the overviews. ``tags``: metadata items (the
    date: :func:`date_tags`). ``path`` appears whole or not at all.
    """
    tmp = path.with_name(path.name + ".tmp.tif")
    t0, t1, t2, t3, t4, t5 = transform
    profile = {
        "driver": "GTiff",
        "width": width_px,
        "height": height_px,
        "count": 3,
        "dtype": "uint8",
        "crs": crs,
        "transform": Affine(t1, t2, t0, t4, t5, t3),
        "tiled": True,
        "blockxsize": 512,
        "blockysize": 512,
        "compress": "DEFLATE",
        "predictor": 2,
        "zlevel": 1,
        "photometric": "RGB",
        "BIGTIFF": "IF_SAFER",
    }
    block = 2048
    try:
        with rasterio.open(tmp, "w", **profile) as dst:
            for y0 in range(0, height_px, block):
                for x0 in range(0, width_px, block):
                    w = min(block, width_px - x0)
                    h = min(block, height_px - y0)
                    bgr = tiles(x0, y0, w, h)
                    rgb = np.ascontiguousarray(bgr[:, :, 2::-1].transpose(2, 0, 1))
                    dst.write(rgb, window=Window(x0, y0, w, h))
            dst.update_tags(**(tags or {}))
        compression = (
            {"COMPRESS": "DEFLATE", "PREDICTOR": "2"}
            if lossless
            else {"COMPRESS": "JPEG", "QUALITY": str(jpeg_quality)}
        )
        cog_copy(
            tmp,
            path,
            **compression,
            BLOCKSIZE="512",
            OVERVIEW_RESAMPLING="AVERAGE",
            BIGTIFF="IF_SAFER",
            NUM_THREADS="2",
        )
    except RasterioError as err:
        raise map_error(str(path), f"cannot write the GeoTIFF ({err})") from None
    finally:
        tmp.unlink(missing_ok=True)


def cog_copy(src: Path, out: Path, **options: str) -> None:
    """``src`` copied as a COG to ``out`` through a temporary file renamed at the end (an
    interrupted copy leaves no half-written ``out``)."""
    part = out.with_name(out.name + ".part")
    try:
        rio_copy(src, part, driver="COG", **options)
        os.replace(part, out)
    finally:
        part.unlink(missing_ok=True)


class GeoTiffDem(TiledSurface, _GeoTiffFile):
    """A GeoTIFF elevation model (heights AMSL, any CRS) sampled on a map's pixel grid.

    Each surface tile reads only the DEM window under it (plus a margin), fills nodata from
    the neighbours (GDAL's inverse-distance fill, with one warning naming the file) and
    samples it bilinearly at the map's level pixel centres; another CRS than the map's goes
    through GDAL's transform on a 17 x 17 lattice per tile, interpolated in between (far
    below a DEM pixel over a tile).
    """

    _LATTICE = 17
    _MARGIN_PX = 24

    def __init__(self, path: Path, map_source: MapSource) -> None:
        super().__init__(map_source)
        src = self._open_file(path, "--dem: ")
        self._nodata = src.nodata
        self._same_crs = src.crs.to_string() == map_source.georef.crs
        self._dem_crs = src.crs.to_string()
        inv = ~src.transform
        self._inv = (inv.a, inv.b, inv.c, inv.d, inv.e, inv.f)

    def _dem_px(
        self, level: int, tx: int, ty: int
    ) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """Continuous DEM pixel coordinates (centre-integral) of a tile's pixel centres."""
        n = TILE_PX if self._same_crs else self._LATTICE
        xs, ys = self.level_centres_crs(level, tx, ty, n)
        if not self._same_crs:
            tx_, ty_ = warp_transform(self.map.georef.crs, self._dem_crs, xs.ravel(), ys.ravel())
            xs = np.asarray(tx_).reshape(n, n)
            ys = np.asarray(ty_).reshape(n, n)
        a, b, c, d, e, f = self._inv
        col = a * xs + b * ys + c - 0.5
        row = d * xs + e * ys + f - 0.5
        if n != TILE_PX:
            # Lattice node k sits at tile pixel k * (TILE_PX - 1) / (n - 1): bilinear in
            # float64 as two matrix products (remap's weights are quantised to 1/32).
            q = np.arange(TILE_PX) * ((n - 1) / (TILE_PX - 1))
            k = np.minimum(np.floor(q).astype(np.int64), n - 2)
            f = q - k
            w = np.zeros((TILE_PX, n))
            w[np.arange(TILE_PX), k] = 1.0 - f
            w[np.arange(TILE_PX), k + 1] = f
            col = w @ col @ w.T
            row = w @ row @ w.T
        return col, row

    def _make_tile(self, level: int, tx: int, ty: int) -> npt.NDArray[np.float32]:
        col, row = self._dem_px(level, tx, ty)
        m = self._MARGIN_PX
        x0 = math.floor(float(col.min())) - m
        y0 = math.floor(float(row.min())) - m
        x1 = math.ceil(float(col.max())) + m + 1
        y1 = math.ceil(float(row.max())) + m + 1
        src = self._src
        with self._lock:
            data = src.read(
                1, window=Window(x0, y0, x1 - x0, y1 - y0), boundless=True, masked=True
            ).astype(np.float32)
        inside = np.zeros(data.shape, dtype=bool)
        inside[
            max(0, -y0) : max(0, min(data.shape[0], src.height - y0)),
            max(0, -x0) : max(0, min(data.shape[1], src.width - x0)),
        ] = True
        valid = ~np.ma.getmaskarray(data) & inside & np.isfinite(data.filled(np.nan))
        values = np.asarray(data.filled(np.nan), dtype=np.float32)
        missing = ~valid
        if missing.any():
            # Ground beyond the extent is said where the flight meets it (camera.coverage):
            # a tile read around the flight often reaches past an edge nothing flies over.
            if (missing & inside).any():
                self.warn(f"--dem {self.path}: nodata holes in the DEM, filled from the neighbours")
            values = _fill_from_neighbours(values, valid)
        heights: npt.NDArray[np.float32] = cv2.remap(  # type: ignore[assignment]
            values,
            (col - x0).astype(np.float32),
            (row - y0).astype(np.float32),
            interpolation=cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
        return heights

    def coverage_at(self, lat_deg: float, lon_deg: float) -> str | None:
        """None where the DEM has a height; ``"outside"`` beyond its extent, ``"nodata"`` in
        one of its holes (heights there are extended or filled, see :meth:`_make_tile`)."""
        if self._same_crs:
            x, y = self.map.georef.px_to_crs(*self.map.latlon_to_map_px(lat_deg, lon_deg))
        else:
            xs, ys = warp_transform("EPSG:4326", self._dem_crs, [lon_deg], [lat_deg])
            x, y = float(xs[0]), float(ys[0])
        a, b, c, d, e, f = self._inv
        col, row = math.floor(a * x + b * y + c), math.floor(d * x + e * y + f)
        src = self._src
        if not (0 <= col < src.width and 0 <= row < src.height):
            return "outside"
        with self._lock:
            value = src.read(1, window=Window(col, row, 1, 1), masked=True)
        if np.ma.getmaskarray(value).any() or not np.isfinite(value.filled(np.nan)).all():
            return "nodata"
        return None

    def describe(self) -> dict[str, Any]:
        """Provenance: file name, SHA-256, CRS."""
        return self._provenance("geotiff-dem", self._dem_crs)

    def close(self) -> None:
        """Close the file."""
        with self._lock:
            self._src.close()


def _fill_from_neighbours(
    values: npt.NDArray[np.float32], valid: npt.NDArray[np.bool_]
) -> npt.NDArray[np.float32]:
    """Missing cells take their nearest valid neighbour's value (none valid: 0 m)."""
    if not valid.any():
        return np.zeros_like(values)
    # Distance transform with labels: index of the nearest valid cell for every cell.
    _dist, labels = cv2.distanceTransformWithLabels(
        (~valid).astype(np.uint8), cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL
    )
    ys, xs = np.nonzero(valid)
    lut = np.zeros(labels.max() + 1, dtype=np.float32)
    lut[labels[ys, xs]] = values[ys, xs]
    out: npt.NDArray[np.float32] = lut[labels]
    out[valid] = values[valid]
    return out
