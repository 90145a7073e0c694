"""``vo``: attitude-compensated visual odometry against keyframes, scaled by the barometer.

Shi-Tomasi corners of a keyframe (the frame decoded at half resolution in grey) are tracked
into each new frame by pyramidal Lucas-Kanade (started from where they were found in the frame
before), cast as rays through the camera, rotated by the AHRS attitude of each exposure (so
bank and pitch do not look like motion), and intersected with flat ground at the height above
home. The ground points of the keyframe's features fix where the new frame must have been to
see them where they are now; the median over the features is the position. A new keyframe is
taken when the features have moved :data:`KEYFRAME_FLOW_PX` or too many were lost.

Why keyframes: between consecutive frames the image moves less than one pixel at 200 m, where
Lucas-Kanade's sub-pixel bias is a few per cent of the motion, and that bias became a scale
error of the whole trajectory (+1.8 % at half resolution, -1.2 % at full resolution, measured
with truth attitude and height). Over 20 pixels the same bias is a fraction of a per cent.
``keyframes=False`` keeps the frame-to-frame method of the first example localizer.

White attitude noise does not accumulate (each keyframe step's error is the difference of two
exposures' errors: the sum telescopes); errors of scale (height), flat ground, heading (the
AHRS yaw) and tracking do: the method drifts, like any odometry.

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
from air_sitl.localize.decode import decode_gray
from air_sitl.localize.inputs import fix_position_ned
from air_sitl.state import GeoPoint

Mat3 = npt.NDArray[np.float64]
F64 = npt.NDArray[np.float64]
Gray = npt.NDArray[Any]  # 8-bit grey image (OpenCV's stubs type arrays loosely)
MIN_TRACKS = 12
KEYFRAME_FLOW_PX = 20.0  # median feature motion (reduced image) that makes a new keyframe
KEYFRAME_KEEP = 0.5  # ... or when fewer than this share of its features are still tracked
HEIGHT_TAU_S = 1.0  # low-pass of the barometer
FIX_SIGMA_M = 1.5
DRIFT_SIGMA_FRACTION = 0.03  # assumed 1-sigma growth: 3 % of the distance flown since the fix


@dataclass(slots=True)
class _Key:
    """A keyframe: its features, their ground points, and where they were seen last."""

    points_px: npt.NDArray[Any]  # float32 features in the reduced image, (N, 1, 2)
    image: Gray
    ground_ned_m: F64  # (N, 3) the features on the flat ground; NaN rows: not on the ground
    last_px: npt.NDArray[Any]  # float32 (N, 1, 2): where each feature was last tracked to
    alive: npt.NDArray[np.bool_]  # (N,) still tracked


class VisualOdometry:
    """Keyframe VO (see the module docstring)."""

    name = "vo"
    # The driver need not decode: the method decodes the JPEG itself at half resolution in
    # grey (three times cheaper than full BGR); given only an image, it converts that.
    needs_image = False

    def __init__(
        self,
        *,
        scale: int = 2,
        max_corners: int = 200,
        window_px: int = 15,
        levels: int = 2,
        keyframes: bool = True,
    ) -> None:
        if scale not in (1, 2):
            msg = f"vo: scale {scale}: expected 1 or 2"
            raise ValueError(msg)
        self.scale = scale
        self.max_corners = max_corners
        self.window_px = window_px  # LK window and pyramid: motion past the guess is small
        self.levels = levels
        self.keyframes = keyframes
        self.home = GeoPoint(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0)
        self.k_inv: Mat3 = np.eye(3)
        self.r_cam_to_body: Mat3 = np.eye(3)
        self._clear()

    def _clear(self) -> None:
        self.key: _Key | None = None
        self.pos_ned_m: F64 | None = None  # the last frame's camera position
        self.start_ned_m: F64 | None = None  # a fix to (re)start from
        self.height_m: float | None = None
        self.prev_t_ns: int | None = None
        self.velocity_ned_m: F64 = np.zeros(3)  # per frame
        self.since_fix_m = 0.0
        self.lost = 0  # frames where tracking failed
        self.tracked = 0
        self.keyframe_count = 0

    def reset(self, context: LocalizerContext) -> None:
        """Forget the previous flight; take the camera of this one."""
        self._clear()
        self.home = context.home
        self.k_inv = np.asarray(np.linalg.inv(context.camera.intrinsics()), dtype=np.float64)
        self.r_cam_to_body = context.camera.r_cam_to_body()

    def _decode(self, obs: Observation) -> Gray | None:
        if obs.jpeg is not None:
            try:
                return decode_gray(obs.jpeg, 2 if self.scale == 2 else 1)
            except ValueError:
                return None
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
        prev = self.pos_ned_m
        if self.start_ned_m is not None:
            pos = self.start_ned_m.copy()
            pos[2] = -h
            self.start_ned_m = None
            self.since_fix_m = 0.0
            self.key = None
        elif prev is None:
            return None
        else:
            pos = self._track(image, r, h, prev)
            self.since_fix_m += float(np.hypot(*(pos[:2] - prev[:2])))
            self.velocity_ned_m = np.asarray(pos - prev, dtype=np.float64)
        self.pos_ned_m = pos
        if self.key is None:
            self.key = self._keyframe(image, r, pos)
        sigma = FIX_SIGMA_M + DRIFT_SIGMA_FRACTION * self.since_fix_m
        var_h = sigma * sigma
        return Estimate(
            frame=obs.frame,
            sim_time_ns=obs.sim_time_ns,
            enu_m=(float(pos[1]), float(pos[0]), float(-pos[2])),
            cov_enu_m2=(var_h, 0.0, 0.0, 0.0, var_h, 0.0, 0.0, 0.0, 1.0),
            quality=float(np.count_nonzero(self.key.alive)) / self.max_corners,
            q_body_to_ned_wxyz=obs.q_ahrs_body_to_ned_wxyz,
        )

    def _keyframe(self, image: Gray, r: Mat3, pos: F64) -> _Key:
        pts = cv2.goodFeaturesToTrack(
            image, maxCorners=self.max_corners, qualityLevel=0.01, minDistance=8
        )
        if pts is None:
            pts = np.zeros((0, 1, 2), np.float32)
        rays = self._rays_ned(pts, r)
        ground = np.full((len(pts), 3), np.nan)
        down = rays[:, 2] > 0.05
        ground[down] = pos + rays[down] * (-pos[2] / rays[down, 2:3])  # down = 0 on the ground
        self.keyframe_count += 1
        return _Key(pts, image, ground, pts.copy(), down.copy())

    def _track(self, image: Gray, r: Mat3, h: float, prev: F64) -> F64:
        guess = prev + self.velocity_ned_m
        guess[2] = -h
        key = self.key
        if key is None or np.count_nonzero(key.alive) < MIN_TRACKS:
            return self._lost(guess)
        idx = np.flatnonzero(key.alive)
        nxt, status, _err = cv2.calcOpticalFlowPyrLK(
            key.image,
            image,
            key.points_px[idx],
            key.last_px[idx].copy(),
            winSize=(self.window_px, self.window_px),
            maxLevel=self.levels,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        ok = status.reshape(-1) == 1
        key.alive[idx[~ok]] = False
        good = idx[ok]
        key.last_px[good] = nxt[ok]
        if len(good) < MIN_TRACKS:
            return self._lost(guess)
        rays = self._rays_ned(nxt[ok], r)
        down = rays[:, 2] > 0.05
        if np.count_nonzero(down) < MIN_TRACKS:
            return self._lost(guess)
        cams = key.ground_ned_m[good[down]] - rays[down] * (h / rays[down, 2:3])
        pos: F64 = np.median(cams, axis=0)
        pos[2] = -h
        self.tracked += 1
        flow = np.median(np.hypot(*(nxt[ok] - key.points_px[good]).reshape(-1, 2).T))
        if (
            not self.keyframes
            or flow > KEYFRAME_FLOW_PX
            or len(good) < KEYFRAME_KEEP * len(key.points_px)
        ):
            self.key = None  # the caller takes this frame as the next keyframe
        return pos

    def _lost(self, guess: F64) -> F64:
        """Tracking failed: constant velocity, and a fresh keyframe at this frame."""
        self.lost += 1
        self.key = None
        return guess
