"""Each date of a procedural map as the product of one aerial survey: what the camera and the
orthophoto production did to the scene the worlds draw (``urban``/``forest`` ``draw``).

- geometry: the orthophoto is misregistered against the others, a global shift of 0.5-1.5 m
  plus a smooth local warp below 1 m (date 0, the reference survey, is exact);
- sensor and processing: haze, exposure, white balance, saturation, gamma, photo-to-photo
  brightness of the mosaic, slight blur and resampling, sensor noise, JPEG compression.

Everything is a function of absolute lattice coordinates, seed and date: a window is drawn
with a margin (aligned on JPEG's 16-pixel blocks in absolute pixels) and cut, so tiles agree on
their shared edges and the same seed and date give the same bytes.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.canvas import DateLook
from air_sitl.maps.procedural.noise import (
    FloatImage,
    key_of,
    unit2,
    unit_of,
    value_noise,
    white_noise,
)

Bgr = npt.NDArray[np.uint8]
DrawFn = Callable[[int, int, int, float, DateLook], npt.NDArray[np.generic]]

JPEG_BLOCK = 16  # a 4:2:0 JPEG's macro block: the alignment of compressed windows
JPEG_MAX_GSD_M = 1.0  # coarser windows are averages of compressed pixels: no blocks left
WARP_CELL_M = 140.0  # feature size of the local warp
BRIGHTNESS_CELL_M = 260.0  # photo-to-photo brightness differences of the mosaic


@dataclass(frozen=True, slots=True)
class Processing:
    """How one survey's camera and orthophoto production rendered the scene."""

    shift_m: float  # global misregistration against date 0
    warp_m: float  # largest local warp
    haze: float  # share of airlight added (0..1)
    exposure: float  # gain after haze
    white_bgr: tuple[float, float, float]  # white balance gains
    saturation: float  # chroma gain about the grey
    gamma: float  # output = input ** (1 / gamma)
    mosaic: float  # amplitude of the brightness differences between photos
    blur_px: float  # Gaussian sigma at 0.5 m pixels (optics, resampling)
    sharpen: float  # unsharp-mask amount (digital surveys are sharpened)
    noise_dn: float  # sensor noise (std, grey levels)
    jpeg_quality: int


# Per date index: 2009 a hazy summer film-like scan, 2012 a warm low-sun digital survey,
# 2016 a crisp cool spring survey. Palettes are drawn vivid; processing brings them to the
# muted colours of real 0.5 m orthophotos (mean HSV saturation about 45).
PROCESSING: tuple[Processing, ...] = (
    Processing(0.0, 0.0, 0.10, 1.02, (1.00, 1.00, 1.00), 0.58, 1.00, 0.04, 0.0, 0.0, 2.5, 82),
    Processing(0.9, 0.8, 0.06, 1.08, (0.90, 1.00, 1.08), 0.38, 1.12, 0.045, 0.0, 0.35, 3.0, 75),
    Processing(1.5, 0.9, 0.14, 0.96, (1.05, 1.02, 0.95), 0.64, 0.92, 0.04, 0.0, 0.15, 3.5, 70),
)


def processing_of(date: DateLook) -> Processing:
    """The processing of a date (later dates than the table repeat its last entry)."""
    return PROCESSING[min(date.index, len(PROCESSING) - 1)]


def margin_px(gsd_m: float, date: DateLook) -> int:
    """Pixels drawn around a window so the warp and blur never reach outside the drawing."""
    p = processing_of(date)
    return math.ceil((p.shift_m + p.warp_m) / gsd_m) + 4


def displacement_m(
    seed: int, date: DateLook, x0: int, y0: int, size: int, gsd_m: float
) -> tuple[FloatImage, FloatImage] | None:
    """(dE, dN) in metres of the ground shown at each pixel against its true place: this
    survey's misregistration. ``None`` for an exactly registered survey (date 0)."""
    p = processing_of(date)
    if p.shift_m == 0.0 and p.warp_m == 0.0:
        return None
    angle = 2.0 * math.pi * unit_of(seed, 0x5A7, date.index)
    cell = WARP_CELL_M / gsd_m
    k = key_of(seed, 0x5A8, date.index)
    # Value noise is about unit std: the local warp's length is squashed below warp_m.
    de = value_noise(k, x0 + 0.5, y0 + 0.5, size, cell)
    dn = value_noise(k + 1, x0 + 0.5, y0 + 0.5, size, cell)
    scale = np.float32(0.5 * p.warp_m) / np.sqrt(1.0 + np.float32(0.25) * (de * de + dn * dn))
    de = de * scale + np.float32(p.shift_m * math.cos(angle))
    dn = dn * scale + np.float32(p.shift_m * math.sin(angle))
    return de.astype(np.float32), dn.astype(np.float32)


def _warp(
    img: npt.NDArray[Any], d: tuple[FloatImage, FloatImage], gsd_m: float, interp: int
) -> npt.NDArray[Any]:
    """Resample ``img`` so pixel p shows what stood at p + d (d in metres, E and N)."""
    h, w = img.shape[:2]
    # Offsets on OpenCV's 1/32-pixel grid: window position and offset then add exactly, so
    # a pixel resamples the same whatever window it is drawn in.
    dx = np.round(d[0] * np.float32(32.0 / gsd_m)) * np.float32(1.0 / 32.0)
    dy = np.round(d[1] * np.float32(32.0 / gsd_m)) * np.float32(1.0 / 32.0)
    xs = np.arange(w, dtype=np.float32)[None, :] + dx
    ys = np.arange(h, dtype=np.float32)[:, None] - dy
    out = cv2.remap(img, xs, ys, interp, borderMode=cv2.BORDER_REPLICATE)
    warped: npt.NDArray[Any] = np.asarray(out, dtype=img.dtype)
    return warped


def _window(x0: int, y0: int, size: int, pad: int, align: int) -> tuple[int, int, int]:
    """Top-left and size of a square window holding (x0, y0, size) plus ``pad``, its corners
    on multiples of ``align`` in absolute pixels."""
    xa = (x0 - pad) // align * align
    ya = (y0 - pad) // align * align
    xb = -(-(x0 + size + pad) // align) * align
    yb = -(-(y0 + size + pad) // align) * align
    return xa, ya, max(xb - xa, yb - ya)


def acquire(
    draw: DrawFn, seed: int, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
) -> Bgr:
    """BGR pixels of one survey over the square (x0, y0, size) at ``gsd_m``: the scene drawn
    by ``draw`` with a margin, misregistered, then developed as the survey's camera did."""
    p = processing_of(date)
    jpeg = gsd_m <= JPEG_MAX_GSD_M
    # With compression, one more block around: a block holding the drawing's rim (where the
    # warp and blur met the edge) would spread into its neighbours' chroma.
    pad = margin_px(gsd_m, date) + (JPEG_BLOCK if jpeg else 0)
    xa, ya, n = _window(x0, y0, size, pad, JPEG_BLOCK if jpeg else 1)
    scene = np.asarray(draw(xa, ya, n, gsd_m, date), dtype=np.uint8)
    d = displacement_m(seed, date, xa, ya, n, gsd_m)
    if d is not None:
        scene = np.asarray(_warp(scene, d, gsd_m, cv2.INTER_CUBIC), dtype=np.uint8)
    img = _develop(scene, p, seed, date, xa, ya, gsd_m)
    if jpeg:
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, p.jpeg_quality])
        assert ok
        img = np.asarray(cv2.imdecode(buf, cv2.IMREAD_COLOR), dtype=np.uint8)
    i, j = y0 - ya, x0 - xa
    return np.ascontiguousarray(img[i : i + size, j : j + size])


def acquire_heights(
    objects: DrawFn, seed: int, x0: int, y0: int, size: int, gsd_m: float, date: DateLook
) -> FloatImage:
    """Heights of the objects as this survey's orthophoto places them (the same warp)."""
    d0 = displacement_m(seed, date, x0, y0, 1, gsd_m)
    if d0 is None:
        return np.asarray(objects(x0, y0, size, gsd_m, date), dtype=np.float32)
    pad = margin_px(gsd_m, date)
    n = size + 2 * pad
    h = np.asarray(objects(x0 - pad, y0 - pad, n, gsd_m, date), dtype=np.float32)
    d = displacement_m(seed, date, x0 - pad, y0 - pad, n, gsd_m)
    assert d is not None
    warped = np.asarray(_warp(h, d, gsd_m, cv2.INTER_LINEAR), dtype=np.float32)
    return np.ascontiguousarray(warped[pad : pad + size, pad : pad + size])


def _develop(
    scene: Bgr, p: Processing, seed: int, date: DateLook, x0: int, y0: int, gsd_m: float
) -> Bgr:
    """The camera and processing: blur or sharpening, saturation, haze, exposure, white
    balance and gamma (one table per channel), the mosaic's photo-to-photo brightness, sensor
    noise."""
    n = scene.shape[0]
    img = scene.astype(np.float32)
    sigma = p.blur_px * 0.5 / gsd_m
    if sigma >= 0.3:
        img = np.asarray(cv2.GaussianBlur(img, (0, 0), sigma), dtype=np.float32)
    if p.sharpen > 0.0 and gsd_m <= JPEG_MAX_GSD_M:
        soft = cv2.GaussianBlur(img, (0, 0), 1.0)
        img = np.asarray(cv2.addWeighted(img, 1.0 + p.sharpen, soft, -p.sharpen, 0.0))
    # Saturation about the grey: x -> grey + s (x - grey), one 3x3 matrix.
    luma = np.array((0.114, 0.587, 0.299), np.float32)
    mix = (1.0 - p.saturation) * np.ones((3, 1), np.float32) * luma[None, :]
    mix += p.saturation * np.eye(3, dtype=np.float32)
    img = np.asarray(cv2.transform(img, mix), dtype=np.float32)
    tone = np.clip(img, 0.0, 255.0).astype(np.uint8)
    tone = np.asarray(cv2.LUT(tone, _tone_table(p)), dtype=np.uint8)
    k = key_of(seed, 0x5A9, date.index)
    bright = _mosaic_gain(seed, date, x0, y0, n, gsd_m, p.mosaic)
    bright += 0.5 * p.mosaic * value_noise(k, x0 + 0.5, y0 + 0.5, n, BRIGHTNESS_CELL_M / gsd_m)
    out = tone.astype(np.float32) * bright[:, :, None]
    if gsd_m <= JPEG_MAX_GSD_M:
        noise = white_noise(key_of(seed, 0x5AA, date.index), x0, y0, n)
        out += (np.float32(p.noise_dn * math.sqrt(3.0)) * noise + np.float32(0.5))[:, :, None]
    developed: Bgr = np.clip(out, 0, 255).astype(np.uint8)
    return developed


@functools.lru_cache(maxsize=16)
def _tone_table(p: Processing) -> npt.NDArray[np.uint8]:
    """Per channel (BGR), grey level in -> out: haze, exposure, white balance, gamma."""
    v = np.arange(256, dtype=np.float64)[:, None] / 255.0
    airlight = np.array((0.80, 0.76, 0.72))  # bluish grey (BGR)
    lin = (v * (1.0 - p.haze) + airlight * p.haze) * np.array(p.white_bgr) * p.exposure
    out = np.power(np.clip(lin, 0.0, 1.0), 1.0 / p.gamma) * 255.0 + 0.5
    table: npt.NDArray[np.uint8] = out.astype(np.uint8).reshape(1, 256, 3)
    return table


NADIR_SPACING_M = (260.0, 420.0)  # photo centres: along the flight lines (E), between them (N)
FLYING_HEIGHT_M = 1500.0


def lean_per_m(seed: int, date: DateLook, e: float, n: float) -> tuple[float, float]:
    """(dE, dN) by which a point 1 m above the ground appears displaced in this survey's
    orthophoto: away from the nadir of the photo the mosaic took it from (relief
    displacement of a standard orthophoto). Date 0, the reference, is a true orthophoto."""
    if date.index == 0:
        return (0.0, 0.0)
    sx, sy, ox, oy = _nadir_grid(seed, date)
    ce = round((e - ox) / sx) * sx + ox
    cn = round((n - oy) / sy) * sy + oy
    return ((e - ce) / FLYING_HEIGHT_M, (n - cn) / FLYING_HEIGHT_M)


def _nadir_grid(seed: int, date: DateLook) -> tuple[float, float, float, float]:
    """Spacing (E, N) and offset (E, N) of this survey's photo centres."""
    sx, sy = NADIR_SPACING_M
    return sx, sy, sx * unit_of(seed, 0x1EA, date.index), sy * unit_of(seed, 0x1EB, date.index)


def _mosaic_gain(
    seed: int, date: DateLook, x0: int, y0: int, n: int, gsd_m: float, amount: float
) -> FloatImage:
    """Brightness of the mosaic's photos: each photo its own gain, brighter on its side away
    from the sun (the hot spot of vegetation and roofs), steps at the seamlines."""
    sx, sy, ox, oy = _nadir_grid(seed, date)
    e = (x0 + np.arange(n, dtype=np.float64) + 0.5) * gsd_m
    north = -(y0 + np.arange(n, dtype=np.float64) + 0.5) * gsd_m
    i = np.round((e - ox) / sx)
    j = np.round((north - oy) / sy)
    gain = unit2(i.astype(np.int64)[None, :], j.astype(np.int64)[:, None], key_of(seed, 0x5AB))
    fe = (e - (i * sx + ox)) / (0.5 * sx)
    fn = (north - (j * sy + oy)) / (0.5 * sy)
    sun_e, sun_n = date.sun_dir()
    away = -(fe[None, :] * sun_e + fn[:, None] * sun_n)
    out: FloatImage = (1.0 + amount * ((2.0 * gain - 1.0) + 0.8 * away)).astype(np.float32)
    return out
