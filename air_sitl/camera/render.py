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
import threading
from dataclasses import dataclass
from typing import cast

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.model import CameraModel
from air_sitl.frames import ned2geodetic
from air_sitl.maps.base import FILL_BGRX, TILE_PX, MapSource
from air_sitl.maps.procedural.noise import key_of
from air_sitl.state import CameraFrame, SimSample, VehicleState

Mat3 = npt.NDArray[np.float64]
Image = npt.NDArray[np.uint8]

FILL_BGR: tuple[int, int, int] = FILL_BGRX[:3]
MAX_MOSAIC_HALF_PX = 2048  # limit of the map area read for one frame, per side, at its level
_MIN_DOWN = 1e-6  # rays flatter than this (horizon) count as missing the ground
_NOISE_BANK_FACTOR = 2


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

    def __init__(self, map_source: MapSource, camera: CameraModel, *, seed: int = 0) -> None:
        self.map = map_source
        self.camera = camera
        self.seed = seed
        self._k_inv = np.linalg.inv(camera.intrinsics())
        self._r_c2b = camera.r_cam_to_body()
        # Noise: a pre-drawn bank split into its positive and negative parts (uint8), so a
        # frame costs two saturating adds (clip(img + n) exactly, as only one part is non-zero
        # per element). A frame takes a contiguous slice at an offset drawn from
        # (seed, frame index): deterministic, and different from frame to frame.
        self._noise_pos: Image | None = None
        self._noise_neg: Image | None = None
        self._local = threading.local()
        self._jacobians: dict[tuple[float, float], tuple[float, float, float, float]] = {}
        self._border = _border_points(camera.width_px, camera.height_px)
        if camera.noise_sigma > 0:
            rng = np.random.default_rng(key_of(seed, 0x4E01))
            n = camera.height_px * camera.width_px * 3 * _NOISE_BANK_FACTOR
            bank = np.rint(rng.standard_normal(n, dtype=np.float32) * camera.noise_sigma)
            self._noise_pos = np.clip(bank, 0, 255).astype(np.uint8)
            self._noise_neg = np.clip(-bank, 0, 255).astype(np.uint8)

    # -- geometry -----------------------------------------------------------------------------
    def ground_affine(self, lat_deg: float, lon_deg: float) -> Mat3:
        """3x3 affine taking local ground (north_m, east_m, 1) at a point to level-0 map px."""
        x0, y0 = self.map.latlon_to_map_px(lat_deg, lon_deg)
        j = self._jacobian(round(lat_deg, 3), round(lon_deg, 3))
        return np.array([[j[0], j[1], x0], [j[2], j[3], y0], [0.0, 0.0, 1.0]])

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
        """The frame's homography and pyramid level for a pose."""
        cam = self.camera
        height = state.alt_amsl_m - self.map.ground_elevation_m
        r_b2n = _quat_matrix(state.q_body_to_ned_wxyz)
        rays = r_b2n @ self._r_c2b @ self._k_inv  # image (u, v, 1) -> NED ray
        m = np.vstack([rays[0] * height, rays[1] * height, rays[2]])  # -> (n, e, 1) homog
        h0 = self.ground_affine(state.lat_deg, state.lon_deg) @ m
        w, h = cam.width_px, cam.height_px
        corners = np.array([[0, 0, 1], [w - 1, 0, 1], [0, h - 1, 1], [w - 1, h - 1, 1]], float)
        down = corners @ rays[2]
        sees_horizon = bool((down <= _MIN_DOWN).any()) or height <= 0
        centre = np.array([cam.cx_px, cam.cy_px, 1.0])
        centre_px: tuple[float, float] | None = None
        if height > 0 and centre @ rays[2] > _MIN_DOWN:
            c = h0 @ centre
            centre_px = (float(c[0] / c[2]), float(c[1] / c[2]))
        level = 0
        if height > 0 and centre @ rays[2] > _MIN_DOWN:
            pts = np.vstack([centre, corners[down > _MIN_DOWN]])
            steps = _steps(h0, pts)
            effective = math.sqrt(steps[0] * steps.max())
            level = self.map.level_for_gsd(effective * self.map.georef.gsd_m)
        return FrameGeometry(h0, level, centre_px, sees_horizon, height)

    def map_xy_px(self, state: VehicleState) -> tuple[float, float] | None:
        """Continuous level-0 map pixel of the image-centre ground point (None: no ground)."""
        return self.geometry(state).center_map_px

    # -- pixels -------------------------------------------------------------------------------
    def render(self, state: VehicleState, geometry: FrameGeometry | None = None) -> Image:
        """The noiseless BGR image seen from ``state`` (``geometry`` if already computed)."""
        cam = self.camera
        g = geometry if geometry is not None else self.geometry(state)
        out_shape = (cam.height_px, cam.width_px, 3)
        if g.height_m <= 0:
            out = np.empty(out_shape, dtype=np.uint8)
            out[:] = FILL_BGR
            return out
        s = 1 << g.level
        off = (s - 1) / 2.0
        to_level = np.array([[1.0 / s, 0.0, -off / s], [0.0, 1.0 / s, -off / s], [0, 0, 1.0]])
        h_lvl = to_level @ g.h_img_to_map0
        x0, y0, x1, y1 = self._footprint(h_lvl, g)
        mosaic, x0, y0 = self._mosaic(g.level, x0, y0, x1, y1)
        shift = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]])
        warped = cv2.warpPerspective(
            mosaic,
            shift @ h_lvl,
            (cam.width_px, cam.height_px),
            flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=FILL_BGRX,
        )
        img = cast(Image, cv2.cvtColor(warped, cv2.COLOR_BGRA2BGR))
        if g.sees_horizon:
            r_b2n = _quat_matrix(state.q_body_to_ned_wxyz)
            down_row = (r_b2n @ self._r_c2b @ self._k_inv)[2]
            u = np.arange(cam.width_px, dtype=np.float64)[None, :]
            v = np.arange(cam.height_px, dtype=np.float64)[:, None]
            sky = down_row[0] * u + down_row[1] * v + down_row[2] <= _MIN_DOWN
            img[sky] = FILL_BGR
        return img

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

    def _footprint(self, h_lvl: Mat3, g: FrameGeometry) -> tuple[int, int, int, int]:
        """Bounding box (inclusive, level pixels, 1 px margin) of the image on the map."""
        border = self._border
        p = border @ h_lvl.T
        ok = p[:, 2] > 1e-12
        xs, ys = p[ok, 0] / p[ok, 2], p[ok, 1] / p[ok, 2]
        # Anchor of the clipping square: the image-centre ground point.
        s = 1 << g.level
        if g.center_map_px is not None:
            ax = (g.center_map_px[0] - (s - 1) / 2.0) / s
            ay = (g.center_map_px[1] - (s - 1) / 2.0) / s
        elif xs.size:
            ax, ay = float(np.median(xs)), float(np.median(ys))
        else:
            ax = ay = 0.0
        lim = MAX_MOSAIC_HALF_PX
        if g.sees_horizon or not xs.size:
            x_lo, x_hi, y_lo, y_hi = ax - lim, ax + lim, ay - lim, ay + lim
        else:
            x_lo, x_hi = max(xs.min(), ax - lim), min(xs.max(), ax + lim)
            y_lo, y_hi = max(ys.min(), ay - lim), min(ys.max(), ay + lim)
        return (
            math.floor(x_lo) - 1,
            math.floor(y_lo) - 1,
            math.ceil(x_hi) + 1,
            math.ceil(y_hi) + 1,
        )

    def add_noise(self, img: Image, index: int) -> Image:
        """Gaussian noise of the camera's sigma, the same for the same (seed, frame index)."""
        if self._noise_pos is None or self._noise_neg is None:
            return img
        size = img.size
        rng = np.random.default_rng(key_of(self.seed, 0x4E02, index))
        offset = int(rng.integers(0, self._noise_pos.size - size + 1))
        pos = self._noise_pos[offset : offset + size].reshape(img.shape)
        neg = self._noise_neg[offset : offset + size].reshape(img.shape)
        out = cast(Image, cv2.add(img, pos))
        cv2.subtract(out, neg, dst=out)
        return out

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
        img = self.add_noise(self.render(state, g), index)
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


def _quat_matrix(q: tuple[float, float, float, float]) -> Mat3:
    w, x, y, z = q
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _steps(h: Mat3, pts: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Largest map-pixel step per image pixel of homography ``h`` at image points (rows)."""
    q = pts @ h.T
    w = q[:, 2:3]
    jx = (h[None, :2, 0] * w - q[:, :2] * h[2, 0]) / w**2  # d(map x, map y)/d(image u)
    jy = (h[None, :2, 1] * w - q[:, :2] * h[2, 1]) / w**2  # d(map x, map y)/d(image v)
    ssum = (jx**2).sum(axis=1) + (jy**2).sum(axis=1)
    det = jx[:, 0] * jy[:, 1] - jx[:, 1] * jy[:, 0]
    disc = np.sqrt(np.maximum(ssum**2 - 4.0 * det**2, 0.0))
    out: npt.NDArray[np.float64] = np.sqrt((ssum + disc) / 2.0)
    return out


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
    from air_sitl.frames import euler2quat

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
