"""Render a camera frame from a map and a pose: one homography warp, noise, JPEG.

The ground is the plane at the map's ground elevation, in the local tangent frame under the
aircraft; ground metres map to map pixels through the map's local affine at the nadir point
(exact to far below a pixel over a camera footprint: UTM scale varies by 1e-6 per km).
The pyramid level comes from the ground sample distance seen by the image (geometric mean of
the centre and the coarsest corner, rounded down to a level), so 100 m to 3000 m stay sharp
and free of aliasing. One level per frame: at extreme attitudes (horizon in view) the far
ground aliases. Rays that miss the ground, or meet it beyond MAX_MOSAIC_HALF_PX level pixels
from the image centre, get the fill colour (black), as does ground outside a bounded map.
A frame is a pure function of (map, camera, state, frame index, seed).
The alpha of the sampled map pixels (0 where a GeoTIFF has nodata, and off the map) tells
how much of a frame shows either (``nodata_fraction``), counted only when the frame's map
window has such pixels: fully covered ground costs one check per new window.
Relief and camera effects are rendered by ``remap`` (a part the Renderer owns); the 3x3
homography arithmetic and FrameGeometry are in ``homography``.
"""

from __future__ import annotations

import math
import sys
import threading
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.homography import (
    MAX_MOSAIC_HALF_PX,
    MIN_DOWN,
    FrameGeometry,
    Mat9,
    border_points,
    max_step,
    mul3,
    quat_rows,
    to_level,
    to_mat,
    tuple9,
)
from air_sitl.camera.model import CameraModel
from air_sitl.camera.remap import RemapPaths
from air_sitl.frames import euler2quat
from air_sitl.maps.base import FILL_BGRX, TILE_PX, MapSource, map_px_jacobian
from air_sitl.maps.procedural.noise import key_of
from air_sitl.maps.surface import SurfaceModel
from air_sitl.state import CameraFrame, SimSample, VehicleState

__all__ = [
    "FILL_BGR",
    "MAX_MOSAIC_HALF_PX",
    "FrameGeometry",
    "Renderer",
    "pose_state",
    "render_camera_frame",
]

Image = npt.NDArray[np.uint8]

FILL_BGR: tuple[int, int, int] = FILL_BGRX[:3]
_COARSE_MAP = 0.5  # warn when a map pixel spans more than 2 image pixels
_NOISE_BANK_FACTOR = 2
_STRIP_BYTES = 320 * 1024  # 4-channel warp output per strip: well inside a core's L2 cache
_STRIP_SOURCE_BYTES = 640 * 1024  # largest map window copied for one strip (see _strip_source)
# Beyond the mosaic (ground clipped far from the centre): the fill colour, but not nodata.
_WARP_BORDER = (*FILL_BGR, 255)


class Renderer:
    """Renders frames of one map for one camera; thread-safe (shared by the bridge's workers)."""

    def __init__(
        self,
        map_source: MapSource,
        camera: CameraModel,
        *,
        seed: int = 0,
        surface: SurfaceModel | None = None,
    ) -> None:
        self.map = map_source
        self.camera = camera
        self.seed = seed
        self.surface = surface  # None: the flat ground plane of the map (frames as before)
        self._warned_gsd = False
        c2b_kinv = camera.r_cam_to_body() @ np.linalg.inv(camera.intrinsics())
        self._c2b_kinv = tuple9(c2b_kinv)  # image (u, v, 1) -> body-frame ray
        # Noise: a pre-drawn bank split into its positive and negative parts (uint8), so a
        # frame costs two saturating adds (clip(img + n) exactly, as only one part is non-zero
        # per element). A frame takes a contiguous slice at an offset drawn from
        # (seed, frame index): deterministic, and different from frame to frame.
        self._noise_pos: Image | None = None
        self._noise_neg: Image | None = None
        self._noise_at = threading.local()  # this thread's last (frame index, size, offset)
        self._local = threading.local()
        self._jacobians: dict[tuple[float, float], tuple[float, float, float, float]] = {}
        self._border = border_points(camera.width_px, camera.height_px)
        w1, h1 = camera.width_px - 1.0, camera.height_px - 1.0
        self._corners = ((0.0, 0.0), (w1, 0.0), (0.0, h1), (w1, h1))
        strips = max(1, math.ceil(camera.width_px * camera.height_px * 4 / _STRIP_BYTES))
        self._strip_rows = math.ceil(camera.height_px / strips)
        # Relief and camera effects: per-pixel maps, in their own part (None: flat, plain).
        self._remap = RemapPaths(self) if surface is not None or camera.has_effects else None
        if camera.noise_sigma > 0:
            rng = np.random.default_rng(key_of(seed, 0x4E01))
            n = camera.height_px * camera.width_px * 3 * _NOISE_BANK_FACTOR
            bank = np.rint(rng.standard_normal(n, dtype=np.float32) * camera.noise_sigma)
            self._noise_pos = np.clip(bank, 0, 255).astype(np.uint8)
            self._noise_neg = np.clip(-bank, 0, 255).astype(np.uint8)

    # -- geometry -----------------------------------------------------------------------------
    def _jacobian(self, lat_deg: float, lon_deg: float) -> tuple[float, float, float, float]:
        """d(map px)/d(north_m, east_m) near a point, cached on a 0.001 degree grid.

        Scale and grid convergence change by about 1e-6 over the 100 m of a grid cell, far
        below a pixel across any frame, so frames of a flight share a few evaluations.
        """
        key = (lat_deg, lon_deg)
        cached = self._jacobians.get(key)
        if cached is not None:
            return cached
        jac = map_px_jacobian(self.map, lat_deg, lon_deg)
        if len(self._jacobians) > 4096:  # bounded: a long flight crosses many cells
            self._jacobians.clear()
        self._jacobians[key] = jac
        return jac

    def geometry(self, state: VehicleState, *, warn: bool = True) -> FrameGeometry:
        """The frame's homography and pyramid level for a pose (``warn``: say once when the
        map is much coarser than the camera; not for frames outside the capture window).

        Scalar arithmetic on 3x3 tuples: a frame needs a few dozen products, for which
        NumPy's per-call overhead would cost more than the arithmetic (this runs 50 times a
        simulated second, beside a warp of under a millisecond).
        """
        cam = self.camera
        h, r, height = self.plane(state)
        corners = self._corners
        downs = [r[6] * u + r[7] * v + r[8] for u, v in corners]
        sees_horizon = height <= 0 or min(downs) <= MIN_DOWN
        cx, cy = cam.cx_px, cam.cy_px
        centre_px: tuple[float, float] | None = None
        level = 0
        if height > 0 and r[6] * cx + r[7] * cy + r[8] > MIN_DOWN:
            cw = h[6] * cx + h[7] * cy + h[8]
            centre_px = ((h[0] * cx + h[1] * cy + h[2]) / cw, (h[3] * cx + h[4] * cy + h[5]) / cw)
            centre_step = max_step(h, cx, cy)
            widest = max(
                [centre_step]
                + [
                    max_step(h, u, v)
                    for (u, v), d in zip(corners, downs, strict=True)
                    if d > MIN_DOWN
                ]
            )
            effective = math.sqrt(centre_step * widest)
            level = self.map.level_for_gsd(effective * self.map.georef.gsd_m)
            if effective < _COARSE_MAP and warn and not self._warned_gsd:
                self._warn_coarse(effective, height)
        g = FrameGeometry(to_mat(h), level, centre_px, sees_horizon, height)
        if self._remap is not None and self.surface is not None and centre_px is not None:
            g = self._remap.relief_centre(state, g)
        return g

    def plane(self, state: VehicleState) -> tuple[Mat9, Mat9, float]:
        """(homography image -> level-0 map px of the ground plane, rotation image (u, v, 1)
        -> NED ray, height above that plane): the plane at the map's ground elevation, or
        over relief through the surface under the aircraft (level, footprint, centre)."""
        if self.surface is None:
            height = state.alt_amsl_m - self.map.ground_elevation_m
        else:
            height = state.alt_amsl_m - self.surface.height_at(state.lat_deg, state.lon_deg)
        r = mul3(quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)  # (u, v, 1) -> NED ray
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        j = self._jacobian(round(state.lat_deg, 3), round(state.lon_deg, 3))
        ground = (j[0], j[1], x0, j[2], j[3], y0, 0.0, 0.0, 1.0)  # (north, east, 1) -> map px
        to_ground = (r[0] * height, r[1] * height, r[2] * height,
                     r[3] * height, r[4] * height, r[5] * height,
                     r[6], r[7], r[8])  # fmt: skip
        return mul3(ground, to_ground), r, height

    def map_xy_px(self, state: VehicleState) -> tuple[float, float] | None:
        """Continuous level-0 map pixel of the image-centre ground point (None: no ground)."""
        return self.geometry(state).center_map_px

    def _warn_coarse(self, effective: float, height_m: float) -> None:
        """Once: the map's pixels are much larger than the camera's at this height."""
        self._warned_gsd = True
        gsd = self.map.georef.gsd_m
        print(
            f"air-sitl: warning: map {self.map.name}: its {gsd:.2f} m pixels are "
            f"{1.0 / effective:.1f}x coarser than the camera's {effective * gsd:.2f} m at "
            f"{height_m:.0f} m above the ground: frames will look blurred",
            file=sys.stderr,
            flush=True,
        )

    # -- pixels -------------------------------------------------------------------------------
    def render(
        self,
        state: VehicleState,
        geometry: FrameGeometry | None = None,
        *,
        noise_index: int | None = None,
    ) -> Image:
        """The BGR image seen from ``state`` (``geometry`` if already computed).

        Noiseless unless ``noise_index`` is given: then the frame's noise is added as well,
        exactly as :meth:`add_noise` would. The image is made in horizontal strips whose
        4-channel warp output stays in the core's cache until it is converted to BGR and
        noised, instead of passing the whole frame through memory three times (the warp
        and the noise are memory-bound; what the strips save shows most when the machine's
        shared cache is busy).
        """
        cam = self.camera
        g = geometry if geometry is not None else self.geometry(state)
        self._local.nodata_px = 0
        out = np.empty((cam.height_px, cam.width_px, 3), dtype=np.uint8)
        noise = self._noise_of(noise_index, out.shape) if noise_index is not None else None
        if g.height_m <= 0:
            out[:] = FILL_BGR
            return out if noise is None else self._noised(out, noise, 0, cam.height_px)
        if self._remap is not None:
            return self._remap.render(state, g, out, noise, noise_index)
        h_lvl = to_level(tuple9(g.h_img_to_map0), g.level)
        x0, y0, x1, y1 = self._footprint(h_lvl, g)
        mosaic, x0, y0 = self._mosaic(g.level, x0, y0, x1, y1)
        a0, a1, a2, a3, a4, a5, a6, a7, a8 = h_lvl
        sky = self._sky(state) if g.sees_horizon else None
        rows = self._strip_rows
        scratch = getattr(self._local, "strip", None)
        if scratch is None:
            scratch = np.empty((rows, cam.width_px, 4), dtype=np.uint8)
            self._local.strip = scratch
        for v0 in range(0, cam.height_px, rows):
            v1 = min(cam.height_px, v0 + rows)
            # Output row v of the strip is image row v0 + v.
            b2, b5, b8 = a1 * v0 + a2, a4 * v0 + a5, a7 * v0 + a8
            strip_lvl = (a0, a1, b2, a3, a4, b5, a6, a7, b8)
            source, sx0, sy0 = mosaic, x0, y0
            if sky is None:
                source, sx0, sy0 = self._strip_source(strip_lvl, v1 - v0, mosaic, x0, y0)
            strip_h = (a0 - sx0 * a6, a1 - sx0 * a7, b2 - sx0 * b8,
                       a3 - sy0 * a6, a4 - sy0 * a7, b5 - sy0 * b8,
                       a6, a7, b8)  # fmt: skip
            warped = cv2.warpPerspective(
                source,
                to_mat(strip_h),
                (cam.width_px, v1 - v0),
                dst=scratch[: v1 - v0],
                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=_WARP_BORDER,
            )
            part = out[v0:v1]
            cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR, dst=part)
            if sky is not None:
                part[sky[v0:v1]] = FILL_BGR
            self._note_nodata(warped, None if sky is None else sky[v0:v1])
            if noise is not None:
                self._noised(part, noise, v0, v1)
        return out

    def _strip_source(
        self, h_strip: Mat9, rows: int, mosaic: Image, mx: int, my: int
    ) -> tuple[Image, int, int]:
        """The mosaic pixels one strip samples, copied into a small per-thread buffer.

        The warp gathers source pixels along several rows at once, which the hardware
        prefetcher does not follow: when the machine's shared cache is busy each access
        waits on memory (measured here: the warp of a 3000 m frame from 0.9 to 2.0 ms).
        Copying the strip's window first reads it row by row, at streaming speed, into a
        buffer the warp then finds in the core's own cache. Returns (pixels, level x0, y0).
        """
        xs, ys = [], []
        w1 = self.camera.width_px - 1.0
        for u, v in ((0.0, 0.0), (w1, 0.0), (0.0, rows - 1.0), (w1, rows - 1.0)):
            w = h_strip[6] * u + h_strip[7] * v + h_strip[8]
            xs.append((h_strip[0] * u + h_strip[1] * v + h_strip[2]) / w)
            ys.append((h_strip[3] * u + h_strip[4] * v + h_strip[5]) / w)
        # Bilinear sampling at x reads columns floor(x) and floor(x) + 1.
        x0 = max(mx, math.floor(min(xs)) - 1)
        y0 = max(my, math.floor(min(ys)) - 1)
        x1 = min(mx + mosaic.shape[1], math.floor(max(xs)) + 3)
        y1 = min(my + mosaic.shape[0], math.floor(max(ys)) + 3)
        if x1 <= x0 or y1 <= y0 or (x1 - x0) * (y1 - y0) * 4 > _STRIP_SOURCE_BYTES:
            return mosaic, mx, my  # off the mosaic, or too large to gain from the copy
        buf = getattr(self._local, "strip_source", None)
        if buf is None:
            buf = np.empty(_STRIP_SOURCE_BYTES, dtype=np.uint8)
            self._local.strip_source = buf
        window = buf[: (x1 - x0) * (y1 - y0) * 4].reshape(y1 - y0, x1 - x0, 4)
        np.copyto(window, mosaic[y0 - my : y1 - my, x0 - mx : x1 - mx])
        return window, x0, y0

    def _sky(self, state: VehicleState) -> npt.NDArray[np.bool_]:
        """Image pixels whose ray misses the ground (at or above the horizon)."""
        cam = self.camera
        r = mul3(quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)
        u = np.arange(cam.width_px, dtype=np.float64)[None, :]
        v = np.arange(cam.height_px, dtype=np.float64)[:, None]
        sky: npt.NDArray[np.bool_] = r[6] * u + r[7] * v + r[8] <= MIN_DOWN
        return sky

    def _mosaic(self, level: int, x0: int, y0: int, x1: int, y1: int) -> tuple[Image, int, int]:
        """Map pixels covering [x0, x1] x [y0, y1] of a level, snapped out to whole tiles.

        The snapped area depends on this frame alone (so the warp, and the bytes, do not
        depend on which thread rendered what before); each thread keeps its last area, and
        consecutive frames of a flight mostly fall in the same one and skip the tile copy.
        """
        t = TILE_PX
        ax0, ay0 = (x0 // t) * t, (y0 // t) * t
        ax1, ay1 = -(-(x1 + 1) // t) * t, -(-(y1 + 1) // t) * t
        key = (level, ax0, ay0, ax1, ay1)
        last = getattr(self._local, "mosaic", None)
        if last is not None and last[0] == key:
            return last[1], ax0, ay0
        img = self.map.read_level(level, ax0, ay0, ax1 - ax0, ay1 - ay0)
        self._local.mosaic = (key, img)
        self._local.holes = bool(img[:, :, 3].min() < 255)
        return img, ax0, ay0

    def _note_nodata(self, warped: npt.NDArray[Any], sky: npt.NDArray[np.bool_] | None) -> None:
        """Count pixels of a 4-channel warp output sampled mostly (alpha below 128) from the
        map's nodata or from off the map, when this thread's mosaic has any (else nothing to
        count: the cost stays off fully covered maps); the sky is not ground."""
        if not self._local.holes:
            return
        low = warped[:, :, 3] < 128
        if sky is not None:
            low &= ~sky
        self._local.nodata_px += int(np.count_nonzero(low))

    def _add_nodata(self, px: int) -> None:
        """Count ``px`` pixels sampled from nodata (the effects' pass counts its own), when
        this thread's mosaic has any."""
        if self._local.holes:
            self._local.nodata_px += px

    def nodata_fraction(self) -> float:
        """Share of the last frame this thread rendered that shows the map's nodata or
        ground off the map (with camera effects: at each pixel's first blur tap)."""
        px: int = getattr(self._local, "nodata_px", 0)
        return px / (self.camera.width_px * self.camera.height_px)

    def _footprint(self, h_lvl: Mat9, g: FrameGeometry) -> tuple[int, int, int, int]:
        """Bounding box (inclusive, level pixels, 1 px margin) of the image on the map.

        A homography maps straight edges to straight edges, so with the whole image on the
        ground (no horizon) the four corners bound the footprint; with the horizon in view,
        points along the edges that meet the ground are used.
        """
        if g.sees_horizon:
            p = self._border @ to_mat(h_lvl).T
            ok = p[:, 2] > 1e-12
            xs = (p[ok, 0] / p[ok, 2]).tolist()
            ys = (p[ok, 1] / p[ok, 2]).tolist()
        else:
            xs, ys = [], []
            for u, v in self._corners:
                w = h_lvl[6] * u + h_lvl[7] * v + h_lvl[8]
                xs.append((h_lvl[0] * u + h_lvl[1] * v + h_lvl[2]) / w)
                ys.append((h_lvl[3] * u + h_lvl[4] * v + h_lvl[5]) / w)
        # Anchor of the clipping square: the image-centre ground point.
        s = 1 << g.level
        if g.center_map_px is not None:
            ax = (g.center_map_px[0] - (s - 1) / 2.0) / s
            ay = (g.center_map_px[1] - (s - 1) / 2.0) / s
        elif xs:
            ax, ay = float(np.median(xs)), float(np.median(ys))
        else:
            ax = ay = 0.0
        lim = MAX_MOSAIC_HALF_PX
        if g.sees_horizon or not xs:
            x_lo, x_hi, y_lo, y_hi = ax - lim, ax + lim, ay - lim, ay + lim
        else:
            x_lo, x_hi = max(min(xs), ax - lim), min(max(xs), ax + lim)
            y_lo, y_hi = max(min(ys), ay - lim), min(max(ys), ay + lim)
        return (
            math.floor(x_lo) - 1,
            math.floor(y_lo) - 1,
            math.ceil(x_hi) + 1,
            math.ceil(y_hi) + 1,
        )

    def add_noise(self, img: Image, index: int) -> Image:
        """Gaussian noise of the camera's sigma, the same for the same (seed, frame index)."""
        noise = self._noise_of(index, img.shape)
        if noise is None:
            return img
        return self._noised(img.copy(), noise, 0, img.shape[0])

    def share_noise(self, other: Renderer) -> None:
        """Take ``other``'s noise (the same camera and seed: the same bank, the same slice for
        a frame): renderers of one frame over several maps then read one bank."""
        assert (other.camera, other.seed) == (self.camera, self.seed), "share_noise: other noise"
        self._noise_pos, self._noise_neg = other._noise_pos, other._noise_neg
        self._noise_at = other._noise_at

    def _noise_of(self, index: int, shape: tuple[int, ...]) -> tuple[Image, Image] | None:
        """The frame's noise as (positive part, negative part) of image shape; None: none."""
        if self._noise_pos is None or self._noise_neg is None:
            return None
        size = math.prod(shape)
        last = getattr(self._noise_at, "last", None)
        if last is not None and last[:2] == (index, size):
            offset = last[2]
        else:
            rng = np.random.default_rng(key_of(self.seed, 0x4E02, index))
            offset = int(rng.integers(0, self._noise_pos.size - size + 1))
            self._noise_at.last = (index, size, offset)
        pos = self._noise_pos[offset : offset + size].reshape(shape)
        neg = self._noise_neg[offset : offset + size].reshape(shape)
        return pos, neg

    @staticmethod
    def _noised(rows: Image, noise: tuple[Image, Image], v0: int, v1: int) -> Image:
        """Add noise rows [v0, v1) to ``rows`` in place: clip(pixel + noise) to 0..255."""
        pos, neg = noise
        cv2.add(rows, pos[v0:v1], dst=rows)
        cv2.subtract(rows, neg[v0:v1], dst=rows)
        return rows

    def encode(self, img: Image) -> bytes:
        """JPEG bytes at the camera's quality."""
        ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, self.camera.jpeg_quality])
        if not ok:  # pragma: no cover - OpenCV always encodes uint8 BGR
            msg = "JPEG encoding failed"
            raise RuntimeError(msg)
        return bytes(buf)

    def frame_jpeg(
        self, state: VehicleState, index: int, *, warn: bool = True
    ) -> tuple[bytes, tuple[int, int]]:
        """Render, add noise, encode: (jpeg, MapX/MapY rounded; (-1, -1) without ground)."""
        g = self.geometry(state, warn=warn)
        img = self.render(state, g, noise_index=index)
        c = g.center_map_px
        xy = (-1, -1) if c is None else (round(c[0]), round(c[1]))
        return self.encode(img), xy


def render_camera_frame(renderer: Renderer, sample: SimSample, index: int) -> CameraFrame:
    """One CameraFrame for a physics sample, synchronously (``render``, remote bridges).

    A frame outside the capture window (a camera on for an aid: take-off, landing) does not
    warn of a coarse map: close to the ground every map is coarse."""
    tick = sample.camera
    in_window = tick is None or tick.capture_index is not None
    jpeg, xy = renderer.frame_jpeg(sample.state, index, warn=in_window)
    return camera_frame(renderer, sample, index, jpeg, xy)


def camera_frame(
    renderer: Renderer, sample: SimSample, index: int, jpeg: bytes, xy: tuple[int, int]
) -> CameraFrame:
    """The CameraFrame of ``renderer``'s last frame on this thread (its JPEG, its map pixel)."""
    return CameraFrame(
        index=index,
        sim_time_ns=sample.state.sim_time_ns,
        jpeg=jpeg,
        width_px=renderer.camera.width_px,
        height_px=renderer.camera.height_px,
        sample=sample,
        map_xy_px=xy,
        nodata_fraction=renderer.nodata_fraction(),
    )


def pose_state(
    lat_deg: float,
    lon_deg: float,
    alt_amsl_m: float,
    *,
    alt_agl_m: float,
    roll_rad: float = 0.0,
    pitch_rad: float = 0.0,
    yaw_rad: float = 0.0,
    sim_time_ns: int = 0,
) -> VehicleState:
    """A still VehicleState at a pose (previews, tests, benchmarks); home is under it."""
    return VehicleState(
        sim_time_ns=sim_time_ns,
        lat_deg=lat_deg,
        lon_deg=lon_deg,
        alt_amsl_m=alt_amsl_m,
        alt_agl_m=alt_agl_m,
        pos_ned_m=(0.0, 0.0, -alt_agl_m),
        q_body_to_ned_wxyz=euler2quat(roll_rad, pitch_rad, yaw_rad),
        roll_rad=roll_rad,
        pitch_rad=pitch_rad,
        yaw_rad=yaw_rad,
        vel_ned_m_s=(0.0, 0.0, 0.0),
        rate_frd_rad_s=(0.0, 0.0, 0.0),
        specific_force_frd_m_s2=(0.0, 0.0, -9.80665),
        airspeed_m_s=0.0,
        on_ground=False,
    )
