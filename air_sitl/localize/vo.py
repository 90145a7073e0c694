"""``vo``: attitude-compensated frame-to-frame visual odometry, scaled by the barometer.

Features tracked between consecutive frames (Shi-Tomasi corners + pyramidal Lucas-Kanade, on
the frame decoded at half resolution in grey) are cast as rays through the camera, rotated by
the AHRS attitude of each exposure (so bank and pitch do not look like motion), and
intersected with flat ground at the height above home. The ground point of a feature seen
from frame k-1 fixes where frame k must have been to see it where it is now; the median over
the features is the position step. White attitude noise does not accumulate (each step's
error is the difference of two exposures' errors: the sum telescopes); errors of scale
(height), flat-ground and tracking do: the method drifts, like any odometry.

Height: the barometer, low-passed (the height changes slowly, the noise does not), or without
one (the bus) the height of the last GNSS fix, held. Start: the first GNSS fix, moved forward
by its velocity to the exposure time; every later fix (archives with denial windows) resets
the position. When tracking fails the last step is repeated (constant velocity).

Rate: every frame is localized (no propagation between frames); ``benchmarks/bench_localize.py``
measures it on one core.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.frames import quat2matrix
from air_sitl.localize.base import Estimate, LocalizerContext, Observation
from air_sitl.localize.inputs import fix_position_ned
from air_sitl.state import GeoPoint

Mat3 = npt.NDArray[np.float64]
Gray = npt.NDArray[Any]  # 8-bit grey image (OpenCV's stubs type arrays loosely)
MIN_TRACKS = 12
HEIGHT_TAU_S = 1.0  # low-pass of the barometer
FIX_SIGMA_M = 1.5
DRIFT_SIGMA_FRACTION = 0.03  # assumed 1-sigma growth: 3 % of the distance flown since the fix


@dataclass(slots=True)
class _Previous:
    """What the last frame left for the next one."""

    points_px: npt.NDArray[Any]  # float32 features in the reduced image, (N, 1, 2)
    image: Gray
    r_cam_to_ned: Mat3
    pos_ned_m: npt.NDArray[np.float64]  # estimated camera position (north, east, down)


class VisualOdometry:
    """Frame-to-frame VO (see the module docstring)."""

    name = "vo"
    # The driver need not decode: the method decodes the JPEG itself at half resolution in
    # grey (three times cheaper than full BGR); given only an image, it converts that.
    needs_image = False

    def __init__(
        self, *, scale: int = 2, max_corners: int = 200, window_px: int = 15, levels: int = 2
    ) -> None:
        if scale not in (1, 2):
            msg = f"vo: scale {scale}: expected 1 or 2"
            raise ValueError(msg)
        self.scale = scale
        self.max_corners = max_corners
        self.window_px = window_px  # LK window and pyramid: inter-frame motion is a few pixels
        self.levels = levels
        self.home = GeoPoint(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0)
        self.k_inv: Mat3 = np.eye(3)
        self.r_cam_to_body: Mat3 = np.eye(3)
        self._clear()

    def _clear(self) -> None:
        self.prev: _Previous | None = None
        self.start_ned_m: npt.NDArray[np.float64] | None = None  # a fix to (re)start from
        self.height_m: float | None = None
        self.prev_t_ns: int | None = None
        self.velocity_ned_m: npt.NDArray[np.float64] = np.zeros(3)  # per frame
        self.since_fix_m = 0.0
        self.lost = 0  # frames where tracking failed
        self.tracked = 0

    def reset(self, context: LocalizerContext) -> None:
        """Forget the previous flight; take the camera of this one."""
        self._clear()
        self.home = context.home
        self.k_inv = np.asarray(np.linalg.inv(context.camera.intrinsics()), dtype=np.float64)
        self.r_cam_to_body = context.camera.r_cam_to_body()

    def _decode(self, obs: Observation) -> Gray | None:
        if obs.jpeg is not None:
            flag = cv2.IMREAD_REDUCED_GRAYSCALE_2 if self.scale == 2 else cv2.IMREAD_GRAYSCALE
            return cv2.imdecode(np.frombuffer(obs.jpeg, np.uint8), flag)
        if obs.image_bgr is None:
            return None
        grey = cv2.cvtColor(obs.image_bgr, cv2.COLOR_BGR2GRAY)
        if self.scale == 2:
            grey = cv2.resize(grey, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)
        return grey

    def _update_height(self, obs: Observation) -> None:
        if obs.baro_alt_rel_m is not None:
            h = max(1.0, obs.baro_alt_rel_m)
            if self.height_m is None or self.prev_t_ns is None:
                self.height_m = h
            else:
                dt = max(0.0, (obs.sim_time_ns - self.prev_t_ns) * 1e-9)
                a = dt / (HEIGHT_TAU_S + dt)
                self.height_m += a * (h - self.height_m)
        elif obs.gnss is not None:
            self.height_m = max(1.0, obs.gnss.alt_amsl_m - self.home.alt_amsl_m)

    def _rays_ned(self, pts: npt.NDArray[Any], r_cam_to_ned: Mat3) -> Mat3:
        full = (pts.reshape(-1, 2).astype(np.float64) + 0.5) * self.scale - 0.5
        homog = np.column_stack([full, np.ones(len(full))])
        rays: Mat3 = (homog @ self.k_inv.T) @ r_cam_to_ned.T
        return rays

    def step(self, obs: Observation) -> Estimate | None:
        """The camera position at this frame; None before the first fix or without height."""
        if obs.gnss is not None:
            self.start_ned_m = np.array(fix_position_ned(obs.gnss, self.home, obs.sim_time_ns))
        self._update_height(obs)
        self.prev_t_ns = obs.sim_time_ns
        image = self._decode(obs)
        h = self.height_m
        if image is None or h is None:
            return None
        r = np.array(quat2matrix(obs.q_ahrs_body_to_ned_wxyz)) @ self.r_cam_to_body
        prev = self.prev
        if self.start_ned_m is not None:
            pos = self.start_ned_m.copy()
            pos[2] = -h
            self.start_ned_m = None
            self.since_fix_m = 0.0
        elif prev is None:
            return None
        else:
            pos = self._track(prev, image, r, h)
            self.since_fix_m += float(np.hypot(*(pos[:2] - prev.pos_ned_m[:2])))
        pts = cv2.goodFeaturesToTrack(
            image, maxCorners=self.max_corners, qualityLevel=0.01, minDistance=8
        )
        if pts is None:
            pts = np.zeros((0, 1, 2), np.float32)
        self.prev = _Previous(pts, image, r, pos)
        sigma = FIX_SIGMA_M + DRIFT_SIGMA_FRACTION * self.since_fix_m
        var_h = sigma * sigma
        return Estimate(
            frame=obs.frame,
            sim_time_ns=obs.sim_time_ns,
            enu_m=(float(pos[1]), float(pos[0]), float(-pos[2])),
            cov_enu_m2=(var_h, 0.0, 0.0, 0.0, var_h, 0.0, 0.0, 0.0, 1.0),
            quality=min(1.0, len(pts) / self.max_corners),
            q_body_to_ned_wxyz=obs.q_ahrs_body_to_ned_wxyz,
        )

    def _track(self, prev: _Previous, image: Gray, r: Mat3, h: float) -> npt.NDArray[np.float64]:
        guess = prev.pos_ned_m + self.velocity_ned_m
        guess[2] = -h
        if len(prev.points_px) < MIN_TRACKS:
            self.lost += 1
            return guess
        nxt, status, _err = cv2.calcOpticalFlowPyrLK(
            prev.image,
            image,
            prev.points_px,
            prev.points_px.copy(),
            winSize=(self.window_px, self.window_px),
            maxLevel=self.levels,
        )
        ok = status.reshape(-1) == 1
        if ok.sum() < MIN_TRACKS:
            self.lost += 1
            return guess
        rays_a = self._rays_ned(prev.points_px[ok], prev.r_cam_to_ned)
        rays_b = self._rays_ned(nxt[ok], r)
        down_ok = (rays_a[:, 2] > 0.05) & (rays_b[:, 2] > 0.05)
        if down_ok.sum() < MIN_TRACKS:
            self.lost += 1
            return guess
        rays_a, rays_b = rays_a[down_ok], rays_b[down_ok]
        h_prev = -prev.pos_ned_m[2]
        ground = prev.pos_ned_m + rays_a * (h_prev / rays_a[:, 2:3])  # down = 0 on the ground
        cams = ground - rays_b * (h / rays_b[:, 2:3])
        pos: npt.NDArray[np.float64] = np.median(cams, axis=0)
        pos[2] = -h
        self.velocity_ned_m = np.asarray(pos - prev.pos_ned_m, dtype=np.float64)
        self.tracked += 1
        return pos
