"""The pixels of ``map fetch``: windows of remote COG assets, mosaicked into one dated COG.

Each item's part over the box is read once (GDAL range requests, only the blocks needed) into
a small local GeoTIFF on the asset's own pixel grid; a date's parts are then mosaicked on the
first one's grid. The parts are the unit of resuming: an interrupted fetch keeps those it read.
With :mod:`air_sitl.maps.geotiff`, the only modules that import rasterio (this one for fetching).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import rasterio
from rasterio.enums import MaskFlags
from rasterio.errors import RasterioError
from rasterio.transform import Affine
from rasterio.warp import Resampling, reproject, transform_bounds
from rasterio.windows import Window

from air_sitl.maps.base import map_error
from air_sitl.maps.geotiff import cog_copy

BBox = tuple[float, float, float, float]
_HTTP_STATUS = re.compile(r"HTTP (?:response code|error code)\D{0,3}(\d{3})", re.IGNORECASE)
# GDAL's retries of answers that may pass (429, 5xx): unless the user's environment says
RETRY_DEFAULTS = {"GDAL_HTTP_MAX_RETRY": "3", "GDAL_HTTP_RETRY_DELAY": "1"}


class AssetReadError(Exception):
    """An asset could not be read; ``status`` is the HTTP status GDAL named (None: other)."""

    def __init__(self, message: str, status: int | None) -> None:
        super().__init__(message)
        self.status = status


def read_asset_window(href: str, bbox_wgs84: BBox, out: Path, gdal: dict[str, str]) -> bool:
    """The part of the raster ``href`` over a WGS84 box, pixels untouched, to a local GeoTIFF
    ``out`` (whole or not at all). False: the raster does not reach into the box."""
    options = {k: v for k, v in RETRY_DEFAULTS.items() if k not in os.environ} | gdal
    try:
        with rasterio.Env(**options), rasterio.open(href) as src:
            left, bottom, right, top = transform_bounds("EPSG:4326", src.crs, *bbox_wgs84)
            t = src.transform
            col0, col1 = sorted(((left - t.c) / t.a, (right - t.c) / t.a))
            row0, row1 = sorted(((top - t.f) / t.e, (bottom - t.f) / t.e))
            c0, r0 = max(0, math.floor(col0)), max(0, math.floor(row0))
            c1, r1 = min(src.width, math.ceil(col1)), min(src.height, math.ceil(row1))
            if c1 <= c0 or r1 <= r0:
                return False
            window = Window(c0, r0, c1 - c0, r1 - r0)
            data = src.read(window=window)
            masked = any(flags != [MaskFlags.all_valid] for flags in src.mask_flag_enums)
            mask = src.dataset_mask(window=window) if masked and src.nodata is None else None
            profile = {
                "driver": "GTiff", "width": window.width, "height": window.height,
                "count": src.count, "dtype": src.dtypes[0], "crs": src.crs,
                "transform": src.window_transform(window), "nodata": src.nodata,
                "tiled": True, "blockxsize": 256, "blockysize": 256, "compress": "DEFLATE",
            }  # fmt: skip
    except RasterioError as err:
        found = _HTTP_STATUS.search(str(err))
        raise AssetReadError(str(err), int(found.group(1)) if found else None) from None
    part = out.with_name(out.name + ".part")
    try:
        with rasterio.open(part, "w", **profile) as dst:
            dst.write(data)
            if mask is not None:
                dst.write_mask(mask)
        os.replace(part, out)
    except RasterioError as err:
        raise map_error(str(out), f"cannot write the part ({err})") from None
    finally:
        part.unlink(missing_ok=True)
    return True


def mosaic_cog(paths: list[Path], bbox_wgs84: BBox, out: Path, tags: dict[str, str]) -> None:
    """One COG over a WGS84 box from several rasters, on the first one's pixel grid, with
    ``tags`` (its date); whole or not at all.

    Sources sharing that grid (CRS, pixel size, aligned origin) are copied by window, pixels
    untouched; others are reprojected onto it (bilinear). Later sources fill only what the
    earlier ones left empty (nodata or outside them).
    """
    try:
        srcs = [rasterio.open(p) for p in paths]
    except RasterioError as err:
        raise map_error(str(paths[0]), f"cannot open the part ({err})") from None
    try:
        ref = srcs[0]
        t = ref.transform
        left, bottom, right, top = transform_bounds("EPSG:4326", ref.crs, *bbox_wgs84)
        col0, col1 = math.floor((left - t.c) / t.a), math.ceil((right - t.c) / t.a)
        row0, row1 = math.floor((top - t.f) / t.e), math.ceil((bottom - t.f) / t.e)
        width, height = col1 - col0, row1 - row0
        out_t = Affine(t.a, 0.0, t.c + col0 * t.a, 0.0, t.e, t.f + row0 * t.e)
        nodata = ref.nodata
        data = np.zeros((ref.count, height, width), dtype=ref.dtypes[0])
        filled = np.zeros((height, width), dtype=bool)
        for src in srcs:
            st = src.transform
            cx = (out_t.c - st.c) / st.a
            cy = (out_t.f - st.f) / st.e
            aligned = (
                src.crs == ref.crs
                and (st.a, st.e) == (t.a, t.e)
                and abs(cx - round(cx)) < 1e-6
                and abs(cy - round(cy)) < 1e-6
            )
            if aligned:
                block = src.read(
                    window=Window(round(cx), round(cy), width, height), boundless=True, masked=True
                )
                valid = ~np.ma.getmaskarray(block).any(axis=0)
                values = block.filled(0)
            else:
                values = np.zeros_like(data)
                for b in range(src.count):
                    reproject(
                        rasterio.band(src, b + 1), values[b], dst_transform=out_t,
                        dst_crs=ref.crs, resampling=Resampling.bilinear, dst_nodata=0,
                    )  # fmt: skip
                valid = (values != 0).any(axis=0)
            take = valid & ~filled
            data[:, take] = values[:, take]
            filled |= take
        tmp = out.with_name(out.name + ".tmp.tif")
        profile = {
            "driver": "GTiff", "width": width, "height": height, "count": ref.count,
            "dtype": ref.dtypes[0], "crs": ref.crs, "transform": out_t, "nodata": nodata,
            "tiled": True, "blockxsize": 256, "blockysize": 256,
        }  # fmt: skip
        try:
            with rasterio.open(tmp, "w", **profile) as dst:
                dst.write(data)
                if nodata is None and not filled.all():
                    dst.write_mask(np.where(filled, 255, 0).astype(np.uint8))
                dst.update_tags(**tags)
            cog_copy(tmp, out, COMPRESS="DEFLATE", BLOCKSIZE="256")
        finally:
            tmp.unlink(missing_ok=True)
    except RasterioError as err:
        raise map_error(str(out), f"cannot write the mosaic ({err})") from None
    finally:
        for s in srcs:
            s.close()
