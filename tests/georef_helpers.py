"""Shared by the map and camera tests: a synthetic UTM grid, GeoTIFF writing, surveyed marks."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import rasterio
from rasterio.transform import Affine
from rasterio.warp import transform as warp_transform

from air_sitl.maps.utm import latlon2utm, utm_zone_of
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


def utm_grid(
    home: GeoPoint, gsd_m: float, half_size_m: float
) -> tuple[str, tuple[float, float, float, float, float, float], int]:
    """CRS, GDAL-order transform and size of a square UTM grid centred near home."""
    zone = utm_zone_of(home.lat_deg, home.lon_deg)
    e, n = latlon2utm(home.lat_deg, home.lon_deg, zone)
    size = round(2 * half_size_m / gsd_m)
    e0 = math.floor((e - half_size_m) / gsd_m) * gsd_m
    n0 = math.ceil((n + half_size_m) / gsd_m) * gsd_m
    return f"EPSG:{zone.epsg}", (e0, gsd_m, 0.0, n0, 0.0, -gsd_m), size


def marks_image(
    size: int, gsd_m: float, spacing_m: float, sigma_m: float
) -> tuple[npt.NDArray[np.uint8], list[tuple[float, float]]]:
    """Grey image with dark Gaussian dots on a grid; dot centres in pixel-centre coordinates."""
    img = np.full((size, size), 200.0, dtype=np.float32)
    sig = sigma_m / gsd_m
    step = spacing_m / gsd_m
    centres = []
    # Pixel coordinates as float32, cut to each dot's box below (not two size x size grids).
    coords = np.arange(size, dtype=np.float32)
    rng = np.random.default_rng(5)
    c = step / 2
    while c < size - step / 2:
        r = step / 2
        while r < size - step / 2:
            cx = c + rng.uniform(-0.15, 0.15) * step
            cy = r + rng.uniform(-0.15, 0.15) * step
            centres.append((cx, cy))
            r += step
        c += step
    rad = int(5 * sig) + 2
    for cx, cy in centres:
        x0, x1 = max(0, int(cx) - rad), min(size, int(cx) + rad)
        y0, y1 = max(0, int(cy) - rad), min(size, int(cy) + rad)
        xx, yy = coords[np.newaxis, x0:x1], coords[y0:y1, np.newaxis]
        g = np.exp(-((xx - cx) ** 2 + (yy - cy) ** 2) / (2 * sig**2))
        img[y0:y1, x0:x1] -= 160.0 * g
    gray = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    return np.dstack([gray, gray, gray]), centres


def write_tif(
    path: Path,
    raster: npt.NDArray[Any],
    crs: str,
    transform: tuple[float, float, float, float, float, float],
    *,
    nodata: float | None = None,
) -> Path:
    """A lossless tiled GeoTIFF, written by rasterio: a BGR image (rows, columns, 3) as RGB,
    or heights (rows, columns) as one band (``transform``: GDAL's six numbers; ``nodata``:
    its tag)."""
    t0, t1, t2, t3, t4, t5 = transform
    bands = raster[np.newaxis] if raster.ndim == 2 else raster[:, :, ::-1].transpose(2, 0, 1)
    count, h, w = bands.shape
    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        width=w,
        height=h,
        count=count,
        dtype=bands.dtype.name,
        crs=crs,
        transform=Affine(t1, t2, t0, t4, t5, t3),
        tiled=True,
        blockxsize=256,
        blockysize=256,
        compress="deflate",
        nodata=nodata,
    ) as dst:
        dst.write(np.ascontiguousarray(bands))
    return path


def px_to_latlon(
    crs: str, transform: tuple[float, float, float, float, float, float], col: float, row: float
) -> tuple[float, float]:
    """Pixel-centre coordinates to WGS84 through GDAL (the independent truth)."""
    return pxs_to_latlons(crs, transform, [(col, row)])[0]


def pxs_to_latlons(
    crs: str,
    transform: tuple[float, float, float, float, float, float],
    points: list[tuple[float, float]],
) -> list[tuple[float, float]]:
    """:func:`px_to_latlon` of many (column, row) points, in one call of GDAL."""
    t0, t1, t2, t3, t4, t5 = transform
    xs = [t0 + t1 * (col + 0.5) + t2 * (row + 0.5) for col, row in points]
    ys = [t3 + t4 * (col + 0.5) + t5 * (row + 0.5) for col, row in points]
    lons, lats = warp_transform(crs, "EPSG:4326", xs, ys)
    return [(float(lat), float(lon)) for lat, lon in zip(lats, lons, strict=True)]


def latlon_to_px(
    crs: str, transform: tuple[float, float, float, float, float, float], lat: float, lon: float
) -> tuple[float, float]:
    """WGS84 to pixel-centre coordinates through GDAL."""
    xs, ys = warp_transform("EPSG:4326", crs, [lon], [lat])
    t0, t1, _t2, t3, _t4, t5 = transform
    return ((float(xs[0]) - t0) / t1 - 0.5, (float(ys[0]) - t3) / t5 - 0.5)
