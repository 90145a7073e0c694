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
"""

from __future__ import annotations

import math
import sys
import threading
from dataclasses import dataclass, replace

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera import effects as fx_mod
from air_sitl.camera import relief
from air_sitl.camera.model import CameraModel
from air_sitl.frames import euler2quat, ned2geodetic, quat_multiply, quat_normalize
from air_sitl.maps.base import FILL_BGRX, TILE_PX, MapSource
from air_sitl.maps.procedural.noise import key_of
from air_sitl.maps.surface import SurfaceModel
from air_sitl.state import CameraFrame, SimSample, VehicleState

Mat3 = npt.NDArray[np.float64]
Mat9 = tuple[float, float, float, float, float, float, float, float, float]
Image = npt.NDArray[np.uint8]
Jac4 = tuple[float, float, float, float]

FILL_BGR: tuple[int, int, int] = FILL_BGRX[:3]
MAX_MOSAIC_HALF_PX = 2048  # limit of the map area read for one frame, per side, at its level
_MIN_DOWN = 1e-6  # rays flatter than this (horizon) count as missing the ground
_COARSE_MAP = 0.5  # warn when a map pixel spans more than 2 image pixels
_NOISE_BANK_FACTOR = 2
_STRIP_BYTES = 320 * 1024  # 4-channel warp output per strip: well inside a core's L2 cache
_STRIP_SOURCE_BYTES = 640 * 1024  # largest map window copied for one strip (see _strip_source)


@dataclass(frozen=True, slots=True)
class FrameGeometry:
    """How one frame maps to the map: homography image -> level-0 map px, level, centre."""

    h_img_to_map0: Mat3
    level: int
    center_map_px: tuple[float, float] | None  # image-centre ground point (None: no ground)
    sees_horizon: bool
    height_m: float


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
        self._c2b_kinv = _tuple9(c2b_kinv)  # image (u, v, 1) -> body-frame ray
        # Noise: a pre-drawn bank split into its positive and negative parts (uint8), so a
        # frame costs two saturating adds (clip(img + n) exactly, as only one part is non-zero
        # per element). A frame takes a contiguous slice at an offset drawn from
        # (seed, frame index): deterministic, and different from frame to frame.
        self._noise_pos: Image | None = None
        self._noise_neg: Image | None = None
        self._local = threading.local()
        self._jacobians: dict[tuple[float, float], tuple[float, float, float, float]] = {}
        self._border = _border_points(camera.width_px, camera.height_px)
        w1, h1 = camera.width_px - 1.0, camera.height_px - 1.0
        self._corners = ((0.0, 0.0), (w1, 0.0), (0.0, h1), (w1, h1))
        strips = max(1, math.ceil(camera.width_px * camera.height_px * 4 / _STRIP_BYTES))
        self._strip_rows = math.ceil(camera.height_px / strips)
        self._pinhole: tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]] | None = None
        self._vignette: npt.NDArray[np.float32] | None = None
        if camera.has_effects:
            assert camera.effects is not None
            k = camera.intrinsics()
            self._pinhole = fx_mod.undistorted_grid(
                camera.width_px, camera.height_px, k, camera.effects.distortion
            )
            if camera.effects.on("vignette"):
                self._vignette = fx_mod.vignette_gain(
                    camera.width_px, camera.height_px, k, *self._pinhole,
                    camera.effects.vignette_power,
                )[:, :, None]  # fmt: skip
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
        d = 50.0
        cols = []
        for dn, de in ((d, 0.0), (0.0, d)):
            la_p, lo_p, _ = ned2geodetic(dn, de, 0.0, lat_deg, lon_deg, 0.0)
            la_m, lo_m, _ = ned2geodetic(-dn, -de, 0.0, lat_deg, lon_deg, 0.0)
            xp, yp = self.map.latlon_to_map_px(la_p, lo_p)
            xm, ym = self.map.latlon_to_map_px(la_m, lo_m)
            cols.append(((xp - xm) / (2 * d), (yp - ym) / (2 * d)))
        jac = (cols[0][0], cols[1][0], cols[0][1], cols[1][1])
        if len(self._jacobians) > 4096:  # bounded: a long flight crosses many cells
            self._jacobians.clear()
        self._jacobians[key] = jac
        return jac

    def geometry(self, state: VehicleState) -> FrameGeometry:
        """The frame's homography and pyramid level for a pose.

        Scalar arithmetic on 3x3 tuples: a frame needs a few dozen products, for which
        NumPy's per-call overhead would cost more than the arithmetic (this runs 50 times a
        simulated second, beside a warp of under a millisecond).
        """
        cam = self.camera
        if self.surface is None:
            height = state.alt_amsl_m - self.map.ground_elevation_m
        else:  # the plane through the surface under the aircraft (level, footprint, centre)
            height = state.alt_amsl_m - self.surface.height_at(state.lat_deg, state.lon_deg)
        r = _mul3(_quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)  # (u, v, 1) -> NED ray
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        j = self._jacobian(round(state.lat_deg, 3), round(state.lon_deg, 3))
        ground = (j[0], j[1], x0, j[2], j[3], y0, 0.0, 0.0, 1.0)  # (north, east, 1) -> map px
        to_ground = (r[0] * height, r[1] * height, r[2] * height,
                     r[3] * height, r[4] * height, r[5] * height,
                     r[6], r[7], r[8])  # fmt: skip
        h = _mul3(ground, to_ground)
        corners = self._corners
        downs = [r[6] * u + r[7] * v + r[8] for u, v in corners]
        sees_horizon = height <= 0 or min(downs) <= _MIN_DOWN
        cx, cy = cam.cx_px, cam.cy_px
        centre_px: tuple[float, float] | None = None
        level = 0
        if height > 0 and r[6] * cx + r[7] * cy + r[8] > _MIN_DOWN:
            cw = h[6] * cx + h[7] * cy + h[8]
            centre_px = ((h[0] * cx + h[1] * cy + h[2]) / cw, (h[3] * cx + h[4] * cy + h[5]) / cw)
            centre_step = _step(h, cx, cy)
            widest = max(
                [centre_step]
                + [
                    _step(h, u, v)
                    for (u, v), d in zip(corners, downs, strict=True)
                    if d > _MIN_DOWN
                ]
            )
            effective = math.sqrt(centre_step * widest)
            level = self.map.level_for_gsd(effective * self.map.georef.gsd_m)
            if effective < _COARSE_MAP and not self._warned_gsd:
                self._warn_coarse(effective, height)
        g = FrameGeometry(_mat(h), level, centre_px, sees_horizon, height)
        if self.surface is not None and centre_px is not None:
            g = self._relief_centre(state, g)
        return g

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
        out = np.empty((cam.height_px, cam.width_px, 3), dtype=np.uint8)
        noise = self._noise_of(noise_index, out.shape) if noise_index is not None else None
        if g.height_m <= 0:
            out[:] = FILL_BGR
            return out if noise is None else self._noised(out, noise, 0, cam.height_px)
        if self._pinhole is not None:
            return self._render_effects(state, g, out, noise, noise_index)
        if self.surface is not None:
            return self._render_relief(state, g, out, noise)
        h_lvl = _to_level(_tuple9(g.h_img_to_map0), g.level)
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
                _mat(strip_h),
                (cam.width_px, v1 - v0),
                dst=scratch[: v1 - v0],
                flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=FILL_BGRX,
            )
            part = out[v0:v1]
            cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR, dst=part)
            if sky is not None:
                part[sky[v0:v1]] = FILL_BGR
            if noise is not None:
                self._noised(part, noise, v0, v1)
        return out

    # -- relief ------------------------------------------------------------------------------
    def _relief_setup(
        self, state: VehicleState, level: int
    ) -> tuple[Mat9, tuple[float, float, float, float], float, float]:
        """(image -> NED ray, d map px / d(north, east), camera level pixel x, y)."""
        r = _mul3(_quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)
        jac = self._jacobian(round(state.lat_deg, 3), round(state.lon_deg, 3))
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        s = 1 << level
        off = (s - 1) / 2.0
        return r, jac, (x0 - off) / s, (y0 - off) / s

    def _relief_window(
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
            corners = self._corners
            border = self._border
        else:
            w1, h1 = size[0] - 1.0, size[1] - 1.0
            corners = ((0.0, 0.0), (w1, 0.0), (0.0, h1), (w1, h1))
            border = _border_points(size[0], size[1])
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
            last = getattr(self._local, "heights", None)
            if last is not None and last[0] == key:
                window = last[1]
            else:
                window = relief.read_window(self.surface, g.level, x0, y0, x1, y1)
                self._local.heights = (key, window)
            if window.h_min >= z_lo and window.h_max <= z_hi:
                break
            z_lo, z_hi = min(z_lo, window.h_min), max(z_hi, window.h_max)
        assert isinstance(window, relief.HeightWindow)
        return window

    def _relief_centre(self, state: VehicleState, g: FrameGeometry) -> FrameGeometry:
        """The geometry with the image-centre ray's first surface point as the centre."""
        r, jac, cx, cy = self._relief_setup(state, g.level)
        window = self._relief_window(state, g, r, jac, cx, cy)
        cam = self.camera
        rays = relief.ray_slopes(
            r, jac, 0, np.array([cam.cx_px], np.float32), np.array([cam.cy_px], np.float32)
        )
        x0, y0 = self.map.latlon_to_map_px(state.lat_deg, state.lon_deg)
        # Level 0 slopes against a level-L window: the march needs level-L slopes.
        s = float(1 << g.level)
        top = np.array([min(window.h_max, state.alt_amsl_m)], np.float32)
        bot = np.array([window.h_min], np.float32)
        z_hit, _ok = relief.march(
            window, cx, cy, state.alt_amsl_m, rays.ax / s, rays.ay / s, top, bot
        )
        d = state.alt_amsl_m - float(z_hit[0])
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
        r, jac, cx, cy = self._relief_setup(state, g.level)
        window = self._relief_window(state, g, r, jac, cx, cy)
        maps, _stats = relief.ground_maps(
            window, r, jac, g.level, cx, cy, state.alt_amsl_m, cam.width_px, cam.height_px
        )
        wh, ww = window.values.shape
        mosaic, mx, my = self._mosaic(g.level, window.x0, window.y0, window.x0 + ww - 1,
                                      window.y0 + wh - 1)  # fmt: skip
        if (mx, my) != (window.x0, window.y0):
            maps = maps + np.array([window.x0 - mx, window.y0 - my], dtype=np.float32)
        warped = cv2.remap(
            mosaic, maps, None, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,  # type: ignore[call-overload]
            borderValue=FILL_BGRX,
        )  # fmt: skip
        cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR, dst=out)
        if g.sees_horizon:
            out[self._sky(state)] = FILL_BGR
        if noise is not None:
            self._noised(out, noise, 0, cam.height_px)
        return out

    # -- camera effects ------------------------------------------------------------------------
    def _pose_maps(
        self, state: VehicleState, level: int, pu: npt.NDArray[np.float64],
        pv: npt.NDArray[np.float64],
    ) -> npt.NDArray[np.float32]:  # fmt: skip
        """Absolute level-pixel map coordinates seen at pinhole points (pu, pv) from a pose.

        Rays missing the ground get a coordinate far off the map (the fill colour).
        """
        cam = self.camera
        if self.surface is None:
            g = self.geometry(state)
            h = _to_level(_tuple9(g.h_img_to_map0), level)
            w = h[6] * pu + h[7] * pv + h[8]
            ok = w > 1e-9
            w = np.where(ok, w, 1.0)
            mx = np.where(ok, (h[0] * pu + h[1] * pv + h[2]) / w, -1e7)
            my = np.where(ok, (h[3] * pu + h[4] * pv + h[5]) / w, -1e7)
            return np.dstack([mx, my]).astype(np.float32)
        # Relief: march a grid covering the pinhole points, then sample it at them.
        g = self.geometry(state)
        m = math.ceil(max(0.0, -float(pu.min()), -float(pv.min()),
                              float(pu.max()) - cam.width_px + 1,
                              float(pv.max()) - cam.height_px + 1)) + 2  # fmt: skip
        r, jac, cx, cy = self._relief_setup(state, level)
        r = (r[0], r[1], r[2] - m * (r[0] + r[1]), r[3], r[4], r[5] - m * (r[3] + r[4]),
             r[6], r[7], r[8] - m * (r[6] + r[7]))  # fmt: skip
        g = FrameGeometry(g.h_img_to_map0, level, g.center_map_px, g.sees_horizon, g.height_m)
        size = (cam.width_px + 2 * m, cam.height_px + 2 * m)
        window = self._relief_window(state, g, r, jac, cx, cy, size)
        maps, _ = relief.ground_maps(
            window, r, jac, level, cx, cy, state.alt_amsl_m, cam.width_px + 2 * m,
            cam.height_px + 2 * m,
        )  # fmt: skip
        maps += np.array([window.x0, window.y0], dtype=np.float32)
        if g.sees_horizon:  # rays that never descend: far off the map (the fill colour)
            down = r[6] * (pu + m) + r[7] * (pv + m) + r[8] > _MIN_DOWN
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

    def _at_time(self, state: VehicleState, dt_s: float) -> VehicleState:
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

    def _blur_samples(self, state: VehicleState, g: FrameGeometry, exposure_s: float) -> int:
        """Sub-exposures so that no image point moves more than half a pixel between two."""
        cam = self.camera
        rate = math.sqrt(sum(w * w for w in state.rate_frd_rad_s))
        speed = math.sqrt(sum(v * v for v in state.vel_ned_m_s))
        corner = math.hypot(cam.width_px, cam.height_px) / 2.0
        # Rotation moves points up to f * rate (more toward the corners); translation
        # f * speed / range, the range at least the height over the ground.
        px_s = rate * (cam.fx_px + corner * corner / cam.fx_px) + cam.fx_px * speed / max(
            g.height_m, 1.0
        )
        return int(min(16, max(1, math.ceil(2.0 * px_s * exposure_s))))

    def _render_effects(
        self,
        state: VehicleState,
        g: FrameGeometry,
        out: Image,
        noise: tuple[Image, Image] | None,
        noise_index: int | None,
    ) -> Image:
        """A frame with the camera's effects (geometry, then light, then the sensor noise)."""
        cam = self.camera
        fx = cam.effects
        assert fx is not None and self._pinhole is not None
        pu, pv = self._pinhole
        exposure = fx.exposure_time_s if fx.on("blur") else 0.0
        count = self._blur_samples(state, g, exposure) if exposure > 0 else 1
        rs = fx.on("rolling-shutter") and fx.line_delay_s > 0
        half = (cam.height_px - 1) / 2.0
        rows = (np.arange(cam.height_px, dtype=np.float32) - np.float32(half))[:, None, None]
        acc = np.zeros((cam.height_px, cam.width_px, 3), dtype=np.float32)
        for k in range(count):
            t = exposure * ((k + 0.5) / count - 0.5)
            if rs:
                # Rows at their own times: the first, middle and last rows' poses, and a
                # quadratic through them per row (Lagrange, in units of half the readout).
                d = fx.line_delay_s * half
                m0, m1, m2 = (self._pose_maps(self._at_time(state, t + s * d), g.level, pu, pv)
                              for s in (-1.0, 0.0, 1.0))  # fmt: skip
                a = rows / np.float32(max(half, 1.0))
                maps = (
                    m1
                    + a * (m2 - m0) * np.float32(0.5)
                    + a * a * ((m0 + m2) * np.float32(0.5) - m1)
                )
            else:
                maps = self._pose_maps(self._at_time(state, t), g.level, pu, pv)
            acc += self._sample_maps(g.level, maps)
        img = acc * np.float32(1.0 / count)
        if fx.on("haze"):
            img = self._haze(state, g, img, fx)
        if self._vignette is not None:
            img *= self._vignette
        if fx.on("exposure"):
            lum = float(img.mean())
            gain = min(fx.exposure_gain_max, max(fx.exposure_gain_min, fx.exposure_target_dn
                                                 / max(lum, 1e-3)))  # fmt: skip
            if noise_index is not None and fx.gain_noise > 0:
                rng = np.random.default_rng(key_of(self.seed, 0x4E03, noise_index))
                gain *= max(0.0, 1.0 + fx.gain_noise * float(rng.standard_normal()))
            img *= np.float32(gain)
        np.clip(np.rint(img), 0, 255, out=img)
        out[:] = img.astype(np.uint8)
        if noise is not None:
            self._noised(out, noise, 0, cam.height_px)
        return out

    def _sample_maps(self, level: int, maps: npt.NDArray[np.float32]) -> npt.NDArray[np.float32]:
        """Colours (float BGR) at absolute level-pixel coordinates, from one mosaic."""
        ok = maps[:, :, 0] > -1e6
        if not ok.any():
            return np.zeros((*maps.shape[:2], 3), dtype=np.float32)
        xs, ys = maps[:, :, 0][ok], maps[:, :, 1][ok]
        cx, cy = float(np.median(xs)), float(np.median(ys))
        lim = MAX_MOSAIC_HALF_PX
        x0 = math.floor(max(float(xs.min()), cx - lim)) - 1
        x1 = math.ceil(min(float(xs.max()), cx + lim)) + 1
        y0 = math.floor(max(float(ys.min()), cy - lim)) - 1
        y1 = math.ceil(min(float(ys.max()), cy + lim)) + 1
        mosaic, mx, my = self._mosaic(level, x0, y0, x1, y1)
        rel = maps - np.array([mx, my], dtype=np.float32)
        warped = cv2.remap(mosaic, rel, None, cv2.INTER_LINEAR,  # type: ignore[call-overload]
                           borderMode=cv2.BORDER_CONSTANT, borderValue=FILL_BGRX)  # fmt: skip
        colour: npt.NDArray[np.float32] = warped[:, :, :3].astype(np.float32)
        return colour

    def _haze(
        self, state: VehicleState, g: FrameGeometry, img: npt.NDArray[np.float32],
        fx: fx_mod.CameraEffects,
    ) -> npt.NDArray[np.float32]:  # fmt: skip
        """Koschmieder: exp(-beta * range) of the radiance, the rest airlight."""
        assert self._pinhole is not None
        pu, pv = self._pinhole
        r = _mul3(_quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)
        dn = r[0] * pu + r[1] * pv + r[2]
        de = r[3] * pu + r[4] * pv + r[5]
        dd = r[6] * pu + r[7] * pv + r[8]
        # Range to the plane under the aircraft (relief: its reference plane); beyond the
        # horizon, a long way.
        ok = dd > _MIN_DOWN
        rng = np.where(ok, max(g.height_m, 0.0) * np.sqrt(dn * dn + de * de + dd * dd)
                       / np.where(ok, dd, 1.0), 1e6)  # fmt: skip
        keep = np.exp(-(3.912 / fx.visibility_m) * rng).astype(np.float32)[:, :, None]
        air = np.array(fx.airlight_bgr, dtype=np.float32)
        return img * keep + air * (np.float32(1.0) - keep)

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
        r = _mul3(_quat_rows(state.q_body_to_ned_wxyz), self._c2b_kinv)
        u = np.arange(cam.width_px, dtype=np.float64)[None, :]
        v = np.arange(cam.height_px, dtype=np.float64)[:, None]
        sky: npt.NDArray[np.bool_] = r[6] * u + r[7] * v + r[8] <= _MIN_DOWN
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
        return img, ax0, ay0

    def _footprint(self, h_lvl: Mat9, g: FrameGeometry) -> tuple[int, int, int, int]:
        """Bounding box (inclusive, level pixels, 1 px margin) of the image on the map.

        A homography maps straight edges to straight edges, so with the whole image on the
        ground (no horizon) the four corners bound the footprint; with the horizon in view,
        points along the edges that meet the ground are used.
        """
        if g.sees_horizon:
            p = self._border @ _mat(h_lvl).T
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

    def _noise_of(self, index: int, shape: tuple[int, ...]) -> tuple[Image, Image] | None:
        """The frame's noise as (positive part, negative part) of image shape; None: none."""
        if self._noise_pos is None or self._noise_neg is None:
            return None
        size = math.prod(shape)
        rng = np.random.default_rng(key_of(self.seed, 0x4E02, index))
        offset = int(rng.integers(0, self._noise_pos.size - size + 1))
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

    def frame_jpeg(self, state: VehicleState, index: int) -> tuple[bytes, tuple[int, int]]:
        """Render, add noise, encode: (jpeg, MapX/MapY rounded; (-1, -1) without ground)."""
        g = self.geometry(state)
        img = self.render(state, g, noise_index=index)
        c = g.center_map_px
        xy = (-1, -1) if c is None else (round(c[0]), round(c[1]))
        return self.encode(img), xy


def render_camera_frame(renderer: Renderer, sample: SimSample, index: int) -> CameraFrame:
    """One CameraFrame for a physics sample, synchronously (``render``, remote bridges)."""
    jpeg, xy = renderer.frame_jpeg(sample.state, index)
    return CameraFrame(
        index=index,
        sim_time_ns=sample.state.sim_time_ns,
        jpeg=jpeg,
        width_px=renderer.camera.width_px,
        height_px=renderer.camera.height_px,
        sample=sample,
        map_xy_px=xy,
    )


def _is_grid(pu: npt.NDArray[np.float64], pv: npt.NDArray[np.float64]) -> bool:
    """Whether (pu, pv) are the plain pixel grid (no distortion)."""
    return bool(pu[0, 1] - pu[0, 0] == 1.0 and pu[0, 0] == 0.0 and pv[0, 0] == 0.0
                and pv[1, 0] == 1.0 and np.array_equal(pu[-1], np.arange(pu.shape[1])))  # fmt: skip


def _border_points(width_px: int, height_px: int, n: int = 9) -> npt.NDArray[np.float64]:
    """Homogeneous image points along the four edges (n per edge)."""
    us = np.linspace(0, width_px - 1, n)
    vs = np.linspace(0, height_px - 1, n)
    return np.concatenate(
        [
            np.stack([us, np.zeros(n), np.ones(n)], 1),
            np.stack([us, np.full(n, height_px - 1.0), np.ones(n)], 1),
            np.stack([np.zeros(n), vs, np.ones(n)], 1),
            np.stack([np.full(n, width_px - 1.0), vs, np.ones(n)], 1),
        ]
    )


def _quat_rows(q: tuple[float, float, float, float]) -> Mat9:
    """Rotation matrix (row-major 9-tuple) of a unit quaternion (w, x, y, z), normalised."""
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return (
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    )  # fmt: skip


def _mul3(a: Mat9, b: Mat9) -> Mat9:
    """Product of two 3x3 matrices given as row-major 9-tuples."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = a
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = b
    return (
        a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
        a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
        a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8,
    )  # fmt: skip


def _tuple9(m: Mat3) -> Mat9:
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = (float(x) for x in m.ravel())
    return (a0, a1, a2, a3, a4, a5, a6, a7, a8)


def _mat(m: Mat9) -> Mat3:
    return np.array(m, dtype=np.float64).reshape(3, 3)


def _to_level(h0: Mat9, level: int) -> Mat9:
    """Homography to level-0 map px -> to level-``level`` px (x_L = (x0 - (s - 1) / 2) / s)."""
    s = float(1 << level)
    off = (s - 1.0) / 2.0
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = h0
    return ((a0 - off * a6) / s, (a1 - off * a7) / s, (a2 - off * a8) / s,
            (a3 - off * a6) / s, (a4 - off * a7) / s, (a5 - off * a8) / s,
            a6, a7, a8)  # fmt: skip


def _step(h: Mat9, u: float, v: float) -> float:
    """Largest map-pixel step per image pixel of homography ``h`` at image point (u, v).

    The largest singular value of the 2x2 Jacobian d(map x, map y)/d(u, v).
    """
    qx = h[0] * u + h[1] * v + h[2]
    qy = h[3] * u + h[4] * v + h[5]
    w = h[6] * u + h[7] * v + h[8]
    w2 = w * w
    xu, yu = (h[0] * w - qx * h[6]) / w2, (h[3] * w - qy * h[6]) / w2
    xv, yv = (h[1] * w - qx * h[7]) / w2, (h[4] * w - qy * h[7]) / w2
    ssum = xu * xu + yu * yu + xv * xv + yv * yv
    det = xu * yv - yu * xv
    disc = math.sqrt(max(ssum * ssum - 4.0 * det * det, 0.0))
    return math.sqrt((ssum + disc) / 2.0)


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
