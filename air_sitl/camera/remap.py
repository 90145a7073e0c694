"""The Renderer's per-pixel paths: ground over relief (ray-marched), and camera effects.

Both make a map of ground coordinates for every image pixel and sample the map with one
``cv2.remap`` (the flat frame without effects is one homography warp, in ``render``). Relief:
each ray's first surface point, marched through a window of heights (``relief``). Effects:
lens distortion, motion blur, rolling shutter, haze, vignetting and auto exposure
(``effects``), over the flat ground or the relief.
"""

from __future__ import annotations

import math
import threading
from typing import Any, Protocol

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera import relief
from air_sitl.camera.effects_frame import EffectsPath
from air_sitl.camera.homography import (
    MAX_MOSAIC_HALF_PX,
    MIN_DOWN,
    FrameGeometry,
    Mat9,
    border_points,
    mul3,
    quat_rows,
    to_level,
    tuple9,
)
from air_sitl.camera.model import CameraModel
from air_sitl.maps.base import FILL_BGRX, TILE_PX, MapSource
from air_sitl.maps.surface import SurfaceModel
from air_sitl.state import VehicleState

Image = npt.NDArray[np.uint8]
Jac4 = tuple[float, float, float, float]
Point = tuple[float, float]
FILL_BGR: tuple[int, int, int] = FILL_BGRX[:3]
_WINDOWS_KEPT = 3  # height windows kept per thread (a frame's search may read two)
_SOURCE_BYTES = 640 * 1024  # largest map window copied for one strip of a relief frame
_SMALL_MOSAIC_BYTES = 2 * 1024 * 1024  # a mosaic this small is remapped without copies


class FrameOwner(Protocol):
    """What the per-pixel paths read from the renderer that owns them (``render.Renderer``;
    this module does not import it: the arrow points from ``render`` to here)."""

    map: MapSource
    camera: CameraModel
    seed: int
    surface: SurfaceModel | None
    _c2b_kinv: Mat9
    _corners: tuple[Point, Point, Point, Point]
    _border: npt.NDArray[np.float64]
    _strip_rows: int

    def geometry(self, state: VehicleState, *, warn: bool = True) -> FrameGeometry:
        """The frame's homography, level and centre."""
        ...

    def plane(self, state: VehicleState) -> tuple[Mat9, Mat9, float]:
        """The ground plane's homography, the rays' rotation and the height over the plane."""
        ...

    def _jacobian(self, lat_deg: float, lon_deg: float) -> tuple[float, float, float, float]: ...

    def _sky(self, state: VehicleState) -> npt.NDArray[np.bool_]: ...

    def _mosaic(self, level: int, x0: int, y0: int, x1: int, y1: int) -> tuple[Image, int, int]: ...

    def _note_nodata(self, warped: npt.NDArray[Any], sky: npt.NDArray[np.bool_] | None) -> None: ...

    def _add_nodata(self, px: int) -> None: ...

    def _noised(self, rows: Image, noise: tuple[Image, Image], v0: int, v1: int) -> Image: ...


class RemapPaths:
    """The relief and camera-effect paths of one Renderer (which owns it); thread-safe.

    It reads the map through its owner (map tiles, the per-cell Jacobian, the sky mask,
    the noise), so both paths share the owner's caches.
    """

    def __init__(self, owner: FrameOwner) -> None:
        self._owner = owner
        self.map = owner.map
        self.camera = camera = owner.camera
        self.surface = owner.surface
        self.seed = owner.seed
        self._local = threading.local()  # this thread's last window of heights
        if self.surface is not None:
            relief.warm()  # the kernels compiled before the first frame, not during it
        # Camera effects: their own part (``effects_frame``), which samples through this one.
        self._effects = EffectsPath(owner, self) if camera.has_effects else None

    def render(
        self,
        state: VehicleState,
        g: FrameGeometry,
        out: Image,
        noise: tuple[Image, Image] | None,
        noise_index: int | None,
    ) -> Image:
        """The frame into ``out``: with the camera's effects if it has any, else over relief."""
        if self._effects is not None:
            return self._effects.render(state, g, out, noise, noise_index)
        return self._render_relief(state, g, out, noise)

    # -- relief -------------------------------------------------------------------------------
    def relief_setup(
        self, state: VehicleState, level: int
    ) -> tuple[Mat9, tuple[float, float, float, float], float, float]:
        """(image -> NED ray, d map px / d(north, east), camera level pixel x, y)."""
        r = mul3(quat_rows(state.q_body_to_ned_wxyz), self._owner._c2b_kinv)
        jac = self._owner._jacobian(round(state.lat_deg, 3), round(state.lon_deg, 3))
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        s = 1 << level
        off = (s - 1) / 2.0
        return r, jac, (x0 - off) / s, (y0 - off) / s

    def relief_window(
        self,
        state: VehicleState,
        g: FrameGeometry,
        r: Mat9,
        jac: Jac4,
        cx: float,
        cy: float,
        size: tuple[int, int] | None = None,
    ) -> relief.HeightWindow:
        """Heights covering every ray's path between the highest and lowest surface seen.

        The footprint is taken at the lowest and the highest height of the window read so
        far until the window holds both (a ray's path between them is a straight segment,
        so the corner (or border) rays bound it); at most MAX_MOSAIC_HALF_PX level pixels
        around the nadir per side.
        """
        assert self.surface is not None
        if size is None:  # the image; else a larger grid (distortion's margin)
            corners = self._owner._corners
            border = self._owner._border
        else:
            w1, h1 = size[0] - 1.0, size[1] - 1.0
            corners = ((0.0, 0.0), (w1, 0.0), (0.0, h1), (w1, h1))
            border = border_points(size[0], size[1])
        pts = border if g.sees_horizon else np.array([(u, v, 1.0) for u, v in corners])
        rays = relief.ray_slopes(
            r, jac, g.level, pts[:, 0].astype(np.float32), pts[:, 1].astype(np.float32)
        )
        ax, ay = rays.ax[rays.down], rays.ay[rays.down]
        z_ref = state.alt_amsl_m - g.height_m
        z_lo = z_hi = z_ref
        lim = MAX_MOSAIC_HALF_PX
        window = None
        for _ in range(4):
            xs, ys = [cx], [cy]
            for z in (z_lo, z_hi):
                d = max(state.alt_amsl_m - z, 0.0)
                xs.extend((cx + d * ax).tolist())
                ys.extend((cy + d * ay).tolist())
            x0 = math.floor(max(min(xs), cx - lim)) - 2
            x1 = math.ceil(min(max(xs), cx + lim)) + 2
            y0 = math.floor(max(min(ys), cy - lim)) - 2
            y1 = math.ceil(min(max(ys), cy + lim)) + 2
            t = TILE_PX  # snapped to whole tiles: the window depends on this frame alone
            key = (g.level, (x0 // t) * t, (y0 // t) * t, -(-(x1 + 1) // t) * t,
                   -(-(y1 + 1) // t) * t)  # fmt: skip
            kept: list[tuple[tuple[int, ...], relief.HeightWindow]] = getattr(
                self._local, "heights", []
            )
            window = next((w for k, w in kept if k == key), None)
            if window is None:
                window = relief.read_window(self.surface, g.level, x0, y0, x1, y1)
                self._local.heights = [(key, window), *kept[: _WINDOWS_KEPT - 1]]
            if window.h_min >= z_lo and window.h_max <= z_hi:
                break
            z_lo, z_hi = min(z_lo, window.h_min), max(z_hi, window.h_max)
        assert isinstance(window, relief.HeightWindow)
        return window

    def _relief_frame(
        self, state: VehicleState, g: FrameGeometry
    ) -> tuple[Mat9, Jac4, float, float, relief.HeightWindow]:
        """relief_setup and relief_window of a frame, kept by the thread for the same state
        and geometry: the frame's centre (``relief_centre``) and its pixels need the same,
        and working them out costs about 0.3 ms."""
        key = (g.level, g.sees_horizon, g.height_m)
        last = getattr(self._local, "frame", None)
        if last is not None and last[0] is state and last[1] == key:
            return last[2]  # type: ignore[no-any-return]
        r, jac, cx, cy = self.relief_setup(state, g.level)
        out = (r, jac, cx, cy, self.relief_window(state, g, r, jac, cx, cy))
        self._local.frame = (state, key, out)
        return out

    def relief_centre(self, state: VehicleState, g: FrameGeometry) -> FrameGeometry:
        """The geometry with the image-centre ray's first surface point as the centre."""
        r, jac, cx, cy, window = self._relief_frame(state, g)
        cam = self.camera
        rays = relief.ray_slopes(
            r, jac, 0, np.array([cam.cx_px], np.float32), np.array([cam.cy_px], np.float32)
        )
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        # Level 0 slopes against a level-L window: the march needs level-L slopes.
        s = float(1 << g.level)
        ax, ay = rays.ax / np.float32(s), rays.ay / np.float32(s)
        z_hit = relief.march_one(window, cx, cy, state.alt_amsl_m, float(ax[0]), float(ay[0]))
        d = state.alt_amsl_m - z_hit
        centre = (x0 + d * float(rays.ax[0]), y0 + d * float(rays.ay[0]))
        return FrameGeometry(g.h_img_to_map0, g.level, centre, g.sees_horizon, g.height_m)

    def _render_relief(
        self,
        state: VehicleState,
        g: FrameGeometry,
        out: Image,
        noise: tuple[Image, Image] | None,
    ) -> Image:
        """Pixels over relief: ray-marched ground points, one remap from the map window."""
        cam = self.camera
        r, jac, cx, cy, window = self._relief_frame(state, g)
        rows = self._owner._strip_rows
        maps, bounds = relief.ground_maps(
            window, r, jac, g.level, cx, cy, state.alt_amsl_m, cam.width_px, cam.height_px,
            rows,
        )  # fmt: skip
        wh, ww = window.values.shape
        mosaic, mx, my = self._owner._mosaic(g.level, window.x0, window.y0, window.x0 + ww - 1,
                                      window.y0 + wh - 1)  # fmt: skip
        sky = self._owner._sky(state) if g.sees_horizon else None
        scratch = getattr(self._local, "strip", None)
        if scratch is None:
            scratch = np.empty((rows, cam.width_px, 4), dtype=np.uint8)
            self._local.strip = scratch
            self._local.strip_maps = np.empty((rows, cam.width_px, 2), dtype=np.float32)
        maps_buf = self._local.strip_maps
        # In strips, each from a copy of the map pixels it samples (as the flat path: the
        # remap then finds its source in the core's cache); the shift of the maps by whole
        # pixels is exact, so the bytes are those of one remap of the whole mosaic.
        for k, v0 in enumerate(range(0, cam.height_px, rows)):
            v1 = min(cam.height_px, v0 + rows)
            source, sx, sy = self._strip_source(mosaic, window.x0 - mx, window.y0 - my,
                                                bounds[k])  # fmt: skip
            part = maps[v0:v1]
            if sx != 0.0 or sy != 0.0:
                # (x, y) pairs as flat rows (NumPy's loop then runs along whole rows), into
                # a buffer kept per thread (a new array per strip costs page faults).
                shift = np.tile(np.array([sx, sy], dtype=np.float32), cam.width_px)
                shifted = maps_buf[: v1 - v0]
                np.subtract(part.reshape(v1 - v0, 2 * cam.width_px), shift,
                            out=shifted.reshape(v1 - v0, 2 * cam.width_px))  # fmt: skip
                part = shifted
            warped = cv2.remap(
                source, part, None, cv2.INTER_LINEAR, dst=scratch[: v1 - v0],  # type: ignore[call-overload]
                borderMode=cv2.BORDER_CONSTANT, borderValue=FILL_BGRX,
            )  # fmt: skip
            rows_out = out[v0:v1]
            cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR, dst=rows_out)
            if sky is not None:
                rows_out[sky[v0:v1]] = FILL_BGR
            self._owner._note_nodata(warped, None if sky is None else sky[v0:v1])
            if noise is not None:
                self._owner._noised(rows_out, noise, v0, v1)
        return out

    def _strip_source(
        self, mosaic: Image, ox: int, oy: int, b: npt.NDArray[np.float32]
    ) -> tuple[Image, float, float]:
        """The mosaic pixels a strip samples (window coordinates in ``b``: x min, y min,
        x max, y max; the window at (ox, oy) in the mosaic), copied into a small per-thread
        buffer; (pixels, their origin in window coordinates). The whole mosaic where the
        strip reaches beyond it or the copy would be large."""
        h, w = mosaic.shape[:2]
        # Bilinear sampling at x reads columns floor(x) and floor(x) + 1.
        x0, y0 = math.floor(float(b[0])) + ox - 1, math.floor(float(b[1])) + oy - 1
        x1, y1 = math.floor(float(b[2])) + ox + 3, math.floor(float(b[3])) + oy + 3
        if (
            mosaic.nbytes <= _SMALL_MOSAIC_BYTES
            or x0 < 0 or y0 < 0 or x1 > w or y1 > h
            or (x1 - x0) * (y1 - y0) * 4 > _SOURCE_BYTES
        ):  # fmt: skip
            return mosaic, float(-ox), float(-oy)
        buf = getattr(self._local, "strip_source", None)
        if buf is None:
            buf = np.empty(_SOURCE_BYTES, dtype=np.uint8)
            self._local.strip_source = buf
        part = buf[: (x1 - x0) * (y1 - y0) * 4].reshape(y1 - y0, x1 - x0, 4)
        np.copyto(part, mosaic[y0:y1, x0:x1])
        return part, float(x0 - ox), float(y0 - oy)

    # -- camera effects ------------------------------------------------------------------------
    def pose_maps(
        self, state: VehicleState, level: int, pu: npt.NDArray[np.float64],
        pv: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.float32]:  # fmt: skip
        """Absolute level-pixel map coordinates seen at pinhole points (pu, pv) from a pose.

        Rays missing the ground get a coordinate far off the map (the fill colour).
        """
        cam = self.camera
        if self.surface is None:
            g = self._owner.geometry(state)
            h = to_level(tuple9(g.h_img_to_map0), level)
            w = h[6] * pu + h[7] * pv + h[8]
            ok = w > 1e-9
            w = np.where(ok, w, 1.0)
            mx = np.where(ok, (h[0] * pu + h[1] * pv + h[2]) / w, -1e7)
            my = np.where(ok, (h[3] * pu + h[4] * pv + h[5]) / w, -1e7)
            return np.dstack([mx, my]).astype(np.float32)
        # Relief: march a grid covering the pinhole points, then sample it at them.
        g = self._owner.geometry(state)
        m = math.ceil(max(0.0, -float(pu.min()), -float(pv.min()),
                              float(pu.max()) - cam.width_px + 1,
                              float(pv.max()) - cam.height_px + 1)) + 2  # fmt: skip
        r, jac, cx, cy = self.relief_setup(state, level)
        r = (r[0], r[1], r[2] - m * (r[0] + r[1]), r[3], r[4], r[5] - m * (r[3] + r[4]),
             r[6], r[7], r[8] - m * (r[6] + r[7]))  # fmt: skip
        g = FrameGeometry(g.h_img_to_map0, level, g.center_map_px, g.sees_horizon, g.height_m)
        size = (cam.width_px + 2 * m, cam.height_px + 2 * m)
        window = self.relief_window(state, g, r, jac, cx, cy, size)
        maps, _ = relief.ground_maps(
            window, r, jac, level, cx, cy, state.alt_amsl_m, cam.width_px + 2 * m,
            cam.height_px + 2 * m,
        )  # fmt: skip
        maps += np.array([window.x0, window.y0], dtype=np.float32)
        if g.sees_horizon:  # rays that never descend: far off the map (the fill colour)
            down = r[6] * (pu + m) + r[7] * (pv + m) + r[8] > MIN_DOWN
        if m == 2 and pu.shape == (cam.height_px, cam.width_px) and _is_grid(pu, pv):
            grid = np.ascontiguousarray(maps[m:-m, m:-m])
            if g.sees_horizon:
                grid[~down] = -1e7
            return grid
        out: npt.NDArray[np.float32] = cv2.remap(  # type: ignore[assignment]
            maps, (pu + m).astype(np.float32), (pv + m).astype(np.float32), cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )  # fmt: skip
        if g.sees_horizon:
            out[~down] = -1e7
        return out


def _is_grid(pu: npt.NDArray[np.float64], pv: npt.NDArray[np.float64]) -> bool:
    """Whether (pu, pv) are the plain pixel grid (no distortion)."""
    return bool(pu[0, 1] - pu[0, 0] == 1.0 and pu[0, 0] == 0.0 and pv[0, 0] == 0.0
                and pv[1, 0] == 1.0 and np.array_equal(pu[-1], np.arange(pu.shape[1])))  # fmt: skip
