"""Frames with camera effects: one pass over the sensor (``effects_kernel``,
``effects_pixels_kernel``), then the gain.

A pixel's colour is the mean of taps along the path its ground point takes over the
exposure (``blur``), each pixel at its row's time (``rolling-shutter``), at the pinhole
point its distorted sensor position sees (``distortion``), times the haze's transmission
plus airlight (``haze``) and the lens's relative illumination (``vignette``); then the auto
exposure's gain (``exposure``) and the sensor noise. The effects' definitions are in
``effects``.

How (issue 34; before it, up to 16 sub-exposures each with three full pose maps and a
remap, 36-150x the plain frame): the homography at any time within the frame's exposure
and readout is the quadratic through those of three poses (start, middle, end of that
span: the pose moves smoothly at the state's velocity and body rates), so each row gets
its own homography at no cost; the blur's path and the haze are smooth over the sensor and
are worked out on a grid of pixels every COARSE_PX, which the pixel loop interpolates; the
blur takes taps about one sensor pixel apart along each pixel's own path (bilinear taps:
their triangles overlap into a box), instead of sub-exposures half a pixel apart at the
fastest point of the frame. Over relief, the middle points come from the relief's maps
(three poses with the rolling shutter, as before) and the paths from the flat grid.

Each pass over the frame is a compiled loop: the maps (``effects_kernel``; and the mosaic
window each strip of STRIP_ROWS rows samples: the remap reads a copy of it), the blur (one
call for all its regions, metering the exposure as it goes), the light with the gain and
the noise (``effects_pixels_kernel``); OpenCV's ``remap`` samples the mosaic. Buffers are
kept per thread.
"""

from __future__ import annotations

import math
import threading
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera import effects as fx_mod
from air_sitl.camera.homography import (
    MAX_MOSAIC_HALF_PX,
    FrameGeometry,
    mul3,
    quat_rows,
    to_level,
)
from air_sitl.frames import ned2geodetic, quat_multiply, quat_normalize
from air_sitl.maps.base import FILL_BGRX
from air_sitl.maps.procedural.noise import key_of
from air_sitl.state import VehicleState

if TYPE_CHECKING:
    from air_sitl.camera.remap import FrameOwner, RemapPaths

Image = npt.NDArray[np.uint8]
F64 = npt.NDArray[np.float64]
F32 = npt.NDArray[np.float32]
COARSE_PX = 16  # the grid of the blur's paths and the haze (both vary slowly over the sensor)
MARGIN_PX = 10  # pixels rendered around the sensor for the blur (16 taps: a path of 16 px)
STRIP_ROWS = 32  # rows of a frame sampled from one window of the mosaic (16: 10% slower)
WINDOW_PX = 160 * 1024  # the largest window copied (640 kB)
_NO_NOISE = np.empty((0, 0, 3), dtype=np.uint8)  # the light's noise where the frame has none


def at_time(state: VehicleState, dt_s: float) -> VehicleState:
    """The pose ``dt_s`` later, moving at the state's velocity and body rates."""
    if dt_s == 0.0:
        return state
    vn, ve, vd = state.vel_ned_m_s
    lat, lon, alt = ned2geodetic(
        vn * dt_s, ve * dt_s, vd * dt_s, state.lat_deg, state.lon_deg, state.alt_amsl_m
    )
    p, q, r = state.rate_frd_rad_s
    ang = math.sqrt(p * p + q * q + r * r) * dt_s  # negative before the frame's time
    if ang != 0.0:
        k = math.sin(ang / 2.0) / (ang / dt_s)
        dq = (math.cos(ang / 2.0), p * k, q * k, r * k)
        quat = quat_normalize(quat_multiply(state.q_body_to_ned_wxyz, dq))
    else:
        quat = state.q_body_to_ned_wxyz
    return replace(state, lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, q_body_to_ned_wxyz=quat)


def _nodes(n: int) -> F64:
    """Grid positions over ``n`` pixels where ``cv2.resize`` (INTER_LINEAR) puts the samples
    of a grid of about n / COARSE_PX: resizing the grid interpolates it bilinearly."""
    count = max(2, math.ceil(n / COARSE_PX))
    return np.asarray((np.arange(count) + 0.5) * (n / count) - 0.5, dtype=np.float64)


def _resize_rows(n: int, size: int) -> F32:
    """For each of ``size`` rows, the two of ``n`` rows and their weights that ``cv2.resize``
    (INTER_LINEAR) blends into it: (first, second, weight of the first, of the second),
    float32 (the rows' indices exact)."""
    scale = n / size
    out = np.empty((size, 4), dtype=np.float32)
    for v in range(size):
        f = np.float32((v + 0.5) * scale - 0.5)
        s = math.floor(f)
        f = np.float32(f - np.float32(s))
        if s < 0:
            s, f = 0, np.float32(0.0)
        if s >= n - 1:
            s, f = n - 1, np.float32(0.0)
        out[v] = (s, min(s + 1, n - 1), np.float32(1.0) - f, f)
    return out


class EffectsPath:
    """The effects part of a Renderer's per-pixel paths (``remap.RemapPaths`` holds it)."""

    def __init__(self, owner: FrameOwner, paths: RemapPaths) -> None:
        # The compiled kernels (air_sitl.compiled: milliseconds built, numba's JIT about a
        # second) load with the first camera that has effects, not with every camera.
        from air_sitl.camera import effects_kernel, effects_pixels_kernel

        self._compiled = effects_kernel
        self._pixels = effects_pixels_kernel
        self._owner = owner
        self._paths = paths
        self.camera = cam = owner.camera
        assert cam.effects is not None
        self.fx = fx = cam.effects
        w, h = cam.width_px, cam.height_px
        k = cam.intrinsics()
        self.pinhole = fx_mod.undistorted_grid(w, h, k, fx.distortion, MARGIN_PX)
        self._pinhole32 = tuple(np.ascontiguousarray(p, dtype=np.float32) for p in self.pinhole)
        m = MARGIN_PX
        self._vignette = (
            fx_mod.vignette_gain(w, h, k, self.pinhole[0][m:-m, m:-m],
                                 self.pinhole[1][m:-m, m:-m], fx.vignette_power)
            if fx.on("vignette")
            else np.ones((h, w), dtype=np.float32)
        )  # fmt: skip
        self._cols, self._rows = _nodes(w), _nodes(h)
        gu, gv = np.meshgrid(self._cols, self._rows)
        self._gu, self._gv = fx_mod.undistort_points(gu, gv, k, fx.distortion)
        self._air = np.array(fx.airlight_bgr, dtype=np.float64)
        self._light = fx.on("haze") or fx.on("vignette") or fx.on("exposure")
        self._ones = np.ones((1, w), dtype=np.float32)  # the haze's share kept, without haze
        self._ones_at = np.tile(np.array([0.0, 0.0, 1.0, 0.0], np.float32), (h, 1))
        self._keep_at = _resize_rows(len(self._rows), h)
        self._local = threading.local()  # this thread's buffers (``_buffer``)

    # -- geometry -----------------------------------------------------------------------------
    def _row_times(self, rows: F64) -> F64:
        """Sensor rows' times after the frame's (the rolling shutter; else zeros)."""
        fx = self.fx
        if not (fx.on("rolling-shutter") and fx.line_delay_s > 0):
            return np.zeros_like(rows)
        out: F64 = (rows - (self.camera.height_px - 1) / 2.0) * fx.line_delay_s
        return out

    def homographies(self, state: VehicleState, level: int) -> tuple[F64, float, float]:
        """(knots, span s, exposure s): image -> level px at -span, 0 and +span (rows of
        ``knots``), span covering the exposure and the readout; see :meth:`at`."""
        fx = self.fx
        exposure = fx.exposure_time_s if fx.on("blur") else 0.0
        edge = float(self.camera.height_px - 1 + MARGIN_PX)
        span = exposure / 2.0 + float(np.abs(self._row_times(np.array([-MARGIN_PX, edge]))).max())
        knots = np.array([
            to_level(self._owner.plane(at_time(state, t))[0], level)
            for t in ((-span, 0.0, span) if span > 0 else (0.0,))
        ])  # fmt: skip
        return knots, span, exposure

    def at(self, knots: F64, span: float, t: F64) -> F64:
        """Homographies at times ``t`` (quadratic through the knots), shape (len(t), 9)."""
        out = np.empty((len(t), 9))
        self._compiled.homographies_at(knots, float(span), t, out)
        return out

    def paths(
        self, knots: F64, span: float, exposure: float
    ) -> tuple[F64, F64, tuple[float, float, float, float] | None]:
        """The blur paths on the coarse grid in image px (x, y components), and the map box
        the grid's points span at the frame's level (None: some rays miss the ground)."""
        t = self._row_times(self._rows)
        h0 = self.at(knots, span, t)
        hl = hh = h0
        if exposure > 0:
            hl = self.at(knots, span, t - exposure / 2.0)
            hh = self.at(knots, span, t + exposure / 2.0)
        ex, ey = np.empty_like(self._gu), np.empty_like(self._gu)
        box = np.empty(4)
        every = self._compiled.grid_paths(h0, hl, hh, self._gu, self._gv, self._cols,
                                          self._rows, ex, ey, box)  # fmt: skip
        if not every:
            return ex, ey, None
        return ex, ey, (float(box[0]), float(box[1]), float(box[2]), float(box[3]))

    def _keep(self, state: VehicleState, g: FrameGeometry) -> tuple[F32, F32]:
        """Haze: the share of the radiance kept over each pixel's range (Koschmieder; the
        range to the plane under the aircraft, over relief its reference plane), from the
        coarse grid: its rows interpolated along the sensor's columns, and each sensor
        row's two of them and their weights (``effects_pixels_kernel._keep_row``; ones without
        haze). The kernels blend a row as they need it: a full-size array and its resize
        cost a frame 0.2-0.3 ms and 1.2 MB written and read twice."""
        cam = self.camera
        if not self.fx.on("haze"):
            return self._ones, self._ones_at
        r = mul3(quat_rows(state.q_body_to_ned_wxyz), self._owner._c2b_kinv)
        coarse = np.empty(self._gu.shape, dtype=np.float32)
        self._compiled.grid_keep(np.array(r), self._gu, self._gv, max(g.height_m, 0.0),
                                 3.912 / self.fx.visibility_m, coarse)  # fmt: skip
        along = self._buffer("keep", (len(self._rows), cam.width_px), np.float32)
        cv2.resize(coarse, (cam.width_px, len(self._rows)), dst=along,
                   interpolation=cv2.INTER_LINEAR)  # fmt: skip
        return along, self._keep_at

    def _remap_strips(self, mosaic: Image, maps: F32, windows: npt.NDArray[np.int64],
                      sharp: Image) -> None:  # fmt: skip
        """``sharp`` sampled from ``mosaic`` at ``maps`` in strips, each from a copy of the
        mosaic's pixels it reads (``windows``, see ``effects_kernel.row_maps``): the rows of
        a frame at an angle to the map's cross many rows of it, and the remap then waits
        on memory for most of its reads; a copy of the window is read row by row and stays
        in the core's cache for the remap."""
        step = STRIP_ROWS
        buf = self._buffer("window", (WINDOW_PX * 4,), np.uint8)
        mh, mw = mosaic.shape[0], mosaic.shape[1]
        linear, constant = cv2.INTER_LINEAR, cv2.BORDER_CONSTANT
        remap = cv2.remap  # positional arguments: a few us less a call than keywords
        for k, (x0, y0, x1, y1) in enumerate(windows.tolist()):
            source = mosaic
            if x1 - x0 < mw or y1 - y0 < mh:
                source = buf[: (y1 - y0) * (x1 - x0) * 4].reshape(y1 - y0, x1 - x0, 4)
                source[...] = mosaic[y0:y1, x0:x1]
            v0 = k * step
            remap(source, maps[v0 : v0 + step], None, linear, sharp[v0 : v0 + step], constant,
                  FILL_BGRX)  # type: ignore[call-overload]  # fmt: skip

    def _buffer(self, name: str, shape: tuple[int, ...], dtype: type) -> npt.NDArray[Any]:
        """A contiguous array of ``shape`` in this thread's buffer ``name``, kept from frame
        to frame (grown to the largest asked for: a new array per frame costs its page
        faults)."""
        kept: dict[str, npt.NDArray[Any]] | None = getattr(self._local, "buffers", None)
        if kept is None:
            kept = self._local.buffers = {}
        size = math.prod(shape)
        found = kept.get(name)
        if found is None or found.size < size:
            found = kept[name] = np.empty(size, dtype=dtype)
        return found[:size].reshape(shape)

    def _mosaic(
        self, g: FrameGeometry, box: tuple[float, float, float, float] | None,
        centre: tuple[float, float], margin: float,
    ) -> tuple[Image, int, int]:  # fmt: skip
        """The map pixels the frame samples: its box (``margin`` level px around it), at
        most MAX_MOSAIC_HALF_PX around the image centre's ground point (all of that when
        the horizon is in view)."""
        lim = MAX_MOSAIC_HALF_PX
        cx, cy = centre
        x_lo, y_lo, x_hi, y_hi = (cx - lim, cy - lim, cx + lim, cy + lim) if box is None else box
        x0 = math.floor(max(x_lo - margin, cx - lim)) - 2
        y0 = math.floor(max(y_lo - margin, cy - lim)) - 2
        x1 = math.ceil(min(x_hi + margin, cx + lim)) + 2
        y1 = math.ceil(min(y_hi + margin, cy + lim)) + 2
        return self._owner._mosaic(g.level, x0, y0, x1, y1)

    # -- pixels -------------------------------------------------------------------------------
    def render(
        self,
        state: VehicleState,
        g: FrameGeometry,
        out: Image,
        noise: tuple[Image, Image] | None,
        noise_index: int | None,
    ) -> Image:
        """The frame with the camera's effects into ``out`` (then the sensor noise)."""
        cam, fx = self.camera, self.fx
        w, h = cam.width_px, cam.height_px
        knots, span, exposure = self.homographies(state, g.level)
        ex, ey, box = self.paths(knots, span, exposure)
        longest = math.sqrt(float((ex * ex + ey * ey).max()))
        pad = 0 if longest < 0.5 else min(MARGIN_PX, math.ceil(longest / 2.0) + 2)
        if self._owner.surface is None:
            rows = self.at(knots, span, self._row_times(np.arange(-pad, h + pad, dtype=float)))
            c = knots[len(knots) // 2]
            cw = c[6] * cam.cx_px + c[7] * cam.cy_px + c[8]
            centre = (0.0, 0.0) if abs(cw) < 1e-12 else (
                (c[0] * cam.cx_px + c[1] * cam.cy_px + c[2]) / cw,
                (c[3] * cam.cx_px + c[4] * cam.cy_px + c[5]) / cw,
            )  # fmt: skip
            # A level pixel spans up to 2 image pixels (``MapSource.level_for_gsd``).
            mosaic, mx, my = self._mosaic(g, box, centre, 2.0 * (pad + 1))
            maps = self._buffer("maps", (h + 2 * pad, w + 2 * pad, 2), np.float32)
            windows = np.empty((-(-(h + 2 * pad) // STRIP_ROWS), 4), dtype=np.int64)
            misses = self._compiled.row_maps(
                self._pinhole32[0], self._pinhole32[1], MARGIN_PX - pad, MARGIN_PX - pad, rows,
                float(mx), float(my), mosaic.shape[1], mosaic.shape[0], STRIP_ROWS, WINDOW_PX, maps,
                windows,
            )  # fmt: skip
        else:
            pad, windows = 0, None  # over relief: the frame's own pixels at its edges
            maps = self._relief_maps(state, g)
            ok = maps[:, :, 0] > -1e6
            misses = int(ok.size - np.count_nonzero(ok))
            if misses < ok.size:
                xs, ys = maps[:, :, 0][ok], maps[:, :, 1][ok]
                centre = (float(np.median(xs)), float(np.median(ys)))
                box = (float(xs.min()), float(ys.min()), float(xs.max()), float(ys.max()))
            else:
                centre, box = (0.0, 0.0), None
            mosaic, mx, my = self._mosaic(g, box, centre, 0.0)
            maps -= np.array([mx, my], dtype=np.float32)
        sharp = self._buffer("sharp", (h + 2 * pad, w + 2 * pad, 4), np.uint8)
        if windows is None:
            cv2.remap(mosaic, maps, None, cv2.INTER_LINEAR, dst=sharp,  # type: ignore[call-overload]
                      borderMode=cv2.BORDER_CONSTANT, borderValue=FILL_BGRX)  # fmt: skip
        else:
            self._remap_strips(mosaic, maps, windows, sharp)
        inner = sharp[pad : pad + h, pad : pad + w]
        sky = maps[pad : pad + h, pad : pad + w, 0] < -1e6 if misses else None
        self._owner._note_nodata(inner, sky)
        frame, meter = sharp, fx.on("exposure")
        keep, keep_at = self._keep(state, g) if self._light else (self._ones, self._ones_at)
        total = 0.0
        if longest >= 0.5:
            frame = self._buffer("blurred", (h, w, 4), np.uint8)
            total = self._pixels.blur(sharp, pad, ex, ey, self._rows, self._cols, keep,
                                      keep_at, self._vignette, self._air, meter,
                                      frame)  # fmt: skip
        elif meter:
            total = self._pixels.light_total(frame, keep, keep_at, self._vignette, self._air)
        if not self._light:
            cv2.cvtColor(frame, cv2.COLOR_BGRA2BGR, dst=out)
            return out if noise is None else self._owner._noised(out, noise, 0, h)
        gain = 1.0
        if meter:
            lum = total / out.size
            target = fx.exposure_target_dn / max(lum, 1e-3)
            gain = min(fx.exposure_gain_max, max(fx.exposure_gain_min, target))
            if noise_index is not None and fx.gain_noise > 0:
                rng = np.random.default_rng(key_of(self._owner.seed, 0x4E03, noise_index))
                gain *= max(0.0, 1.0 + fx.gain_noise * float(rng.standard_normal()))
        pos, neg = noise if noise is not None else (_NO_NOISE, _NO_NOISE)
        self._pixels.light(frame, keep, keep_at, self._vignette, self._air, gain, pos, neg,
                           out)  # fmt: skip
        return out

    def _relief_maps(self, state: VehicleState, g: FrameGeometry) -> npt.NDArray[np.float32]:
        """Level-px ground points of each pixel at its row's time over relief (the rows'
        points between those of the first, middle and last rows' poses, quadratically)."""
        cam, fx = self.camera, self.fx
        m = MARGIN_PX
        pu, pv = self.pinhole[0][m:-m, m:-m], self.pinhole[1][m:-m, m:-m]
        if not (fx.on("rolling-shutter") and fx.line_delay_s > 0):
            return self._paths.pose_maps(state, g.level, pu, pv)
        half = (cam.height_px - 1) / 2.0
        d = fx.line_delay_s * half
        m0, m1, m2 = (self._paths.pose_maps(at_time(state, s * d), g.level, pu, pv)
                      for s in (-1.0, 0.0, 1.0))  # fmt: skip
        rows = (np.arange(cam.height_px, dtype=np.float32) - np.float32(half))[:, None, None]
        a = rows / np.float32(max(half, 1.0))
        maps: npt.NDArray[np.float32] = (
            m1 + a * (m2 - m0) * np.float32(0.5) + a * a * ((m0 + m2) * np.float32(0.5) - m1)
        )
        return maps
