#!/usr/bin/env python3
"""An external localization process on the bus: attitude-compensated frame-to-frame VO.

The pattern every estimator follows: join the bus, read ``camera/info`` and the latest
``mission/status`` (home) and ``gps`` with a query, subscribe to ``imu`` and ``camera/image``,
publish one estimate per frame on ``air/<vehicle>/estimate/<name>``.

The method, deliberately simple: features tracked between consecutive frames (Shi-Tomasi +
pyramidal Lucas-Kanade) are cast as rays through the camera, rotated by the AHRS attitude of
each exposure (so bank and pitch do not look like motion), and intersected with the flat
ground at the height above home. The ground point of a feature seen from frame k-1 fixes where
frame k must have been to see it where it is now; the median over features is the position
step. It starts from the last GNSS fix and the GNSS altitude gives the height (when GNSS is
denied, the last height is kept); horizontally it is pure odometry and drifts.

Run: ``python bridges/example_localizer.py --name ex`` next to ``air-sitl fly --zenoh ...``.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.bus import codec
from air_sitl.bus.args import add_connection_arguments, bus_config_from_args
from air_sitl.bus.keys import KeySpace, check_chunk
from air_sitl.bus.session import Bus, Message, open_bus
from air_sitl.bus.signals import wait_until_signalled
from air_sitl.errors import AirSitlError, BusError
from air_sitl.frames import geodetic2ned, quat2matrix
from air_sitl.state import GeoPoint, Quat

Mat3 = npt.NDArray[np.float64]
Gray = npt.NDArray[Any]  # 8-bit grey image (OpenCV's stubs type arrays loosely)
MIN_TRACKS = 12


@dataclass(slots=True)
class _Previous:
    """What the last frame left for the next one."""

    points_px: npt.NDArray[Any]  # float32 features in the reduced image, (N, 1, 2)
    image: Gray
    r_cam_to_ned: Mat3
    pos_ned_m: npt.NDArray[np.float64]  # estimated camera position (north, east, down)


class VisualOdometry:
    """The estimator: one ``step`` per frame, in frame order."""

    def __init__(self, info: codec.CameraInfo, home: GeoPoint, *, scale: int = 2) -> None:
        self.home = home
        self.scale = scale  # frames decoded at 1/scale resolution (fast, plenty for the flow)
        f = info.focal_px
        cx, cy = (info.width_px - 1) / 2.0, (info.height_px - 1) / 2.0
        self.k_inv = np.linalg.inv(np.array([[f, 0, cx], [0, f, cy], [0, 0, 1.0]]))
        self.r_cam_to_body = np.array(quat2matrix(info.q_cam_to_body_wxyz))
        self.prev: _Previous | None = None
        self.height_m: float | None = None
        self.velocity_ned_m: npt.NDArray[np.float64] = np.zeros(3)  # per frame
        self.lost = 0

    def gps_height(self, fix_alt_amsl_m: float) -> None:
        """Feed a GNSS altitude (smoothed: the vertical noise is several metres)."""
        h = max(1.0, fix_alt_amsl_m - self.home.alt_amsl_m)
        self.height_m = h if self.height_m is None else 0.9 * self.height_m + 0.1 * h

    def _rays_ned(self, pts: npt.NDArray[Any], r_cam_to_ned: Mat3) -> Mat3:
        full = (pts.reshape(-1, 2).astype(np.float64) + 0.5) * self.scale - 0.5
        homog = np.column_stack([full, np.ones(len(full))])
        rays_cam = homog @ self.k_inv.T
        rays: Mat3 = rays_cam @ r_cam_to_ned.T
        return rays

    def step(
        self, jpeg: bytes, q_body_to_ned: Quat, start_ned_m: tuple[float, float] | None
    ) -> npt.NDArray[np.float64] | None:
        """Position (north, east, down) of the camera at this frame; None before a start."""
        flag = cv2.IMREAD_REDUCED_GRAYSCALE_2 if self.scale == 2 else cv2.IMREAD_GRAYSCALE
        image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), flag)
        if image is None or self.height_m is None:
            return None
        r = np.array(quat2matrix(q_body_to_ned)) @ self.r_cam_to_body
        h = self.height_m
        prev = self.prev
        if prev is None:
            if start_ned_m is None:
                return None
            pos = np.array([start_ned_m[0], start_ned_m[1], -h])
        else:
            pos = self._track(prev, image, r, h)
        pts = cv2.goodFeaturesToTrack(image, maxCorners=200, qualityLevel=0.01, minDistance=8)
        if pts is None:
            pts = np.zeros((0, 1, 2), np.float32)
        self.prev = _Previous(pts, image, r, pos)
        return pos

    def _track(self, prev: _Previous, image: Gray, r: Mat3, h: float) -> npt.NDArray[np.float64]:
        guess = prev.pos_ned_m + self.velocity_ned_m
        guess[2] = -h
        if len(prev.points_px) < MIN_TRACKS:
            self.lost += 1
            return guess
        nxt, status, _err = cv2.calcOpticalFlowPyrLK(
            prev.image, image, prev.points_px, prev.points_px.copy(), winSize=(21, 21), maxLevel=3
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
        self.velocity_ned_m = pos - prev.pos_ned_m
        return pos


class Localizer:
    """Bus side of the example: subscriptions, the IMU history, and publishing estimates."""

    def __init__(self, bus: Bus, keys: KeySpace, name: str, *, wait_s: float) -> None:
        self.bus = bus
        self.keys = keys
        self.key_out = keys.estimate(name)
        self._lock = threading.Condition()
        self._imu: deque[tuple[int, Quat]] = deque(maxlen=2000)
        self._last_fix: tuple[float, float, float] | None = None
        self._fix_fresh = False
        self.frames = 0
        self.published = 0
        self.last_frame = -1
        self.errors = 0
        bus.subscribe(keys.imu, self._on_imu)
        bus.subscribe(keys.gps, self._on_gps)
        info = codec.decode_camera_info(self._ask(keys.info, wait_s).payload)
        status = codec.loads(self._ask(keys.mission_status, wait_s).payload, keys.mission_status)
        h = status.get("home")
        if not isinstance(h, dict):
            msg = f"{keys.mission_status}: no home in the status"
            raise BusError(msg)
        home = GeoPoint(
            lat_deg=float(h["lat_deg"]),
            lon_deg=float(h["lon_deg"]),
            alt_amsl_m=float(h["alt_amsl_m"]),
        )
        self.vo = VisualOdometry(info, home)
        for key, handler in ((keys.gps, self._on_gps), (keys.imu, self._on_imu)):
            with contextlib.suppress(BusError):  # the latest value, if there is one yet
                handler(Message(key, bus.query(key, timeout_s=2.0).payload, None))
        self._out = bus.publisher(self.key_out, encoding=codec.JSON_ENCODING, block=True)
        bus.subscribe(keys.image, self._on_image)

    def _ask(self, key: str, wait_s: float) -> Message:
        """Query ``key`` until the simulator answers (it may start after us)."""
        deadline = time.monotonic() + wait_s
        while True:
            try:
                return self.bus.query(key, timeout_s=1.0)
            except BusError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)

    def _on_imu(self, message: Message) -> None:
        imu = codec.decode_imu(message.payload)
        with self._lock:
            self._imu.append((imu.sim_time_ns, imu.q_ahrs_body_to_ned_wxyz))
            self._lock.notify_all()

    def _on_gps(self, message: Message) -> None:
        m = codec.loads(message.payload, message.key)
        fix = (float(m["lat_deg"]), float(m["lon_deg"]), float(m["alt_amsl_m"]))
        with self._lock:
            self._last_fix = fix
            self._fix_fresh = True

    def _attitude_at(self, t_ns: int) -> Quat | None:
        """The AHRS attitude at the exposure (the IMU sample of that step comes first, but on
        another subscriber's thread: give it a moment)."""
        with self._lock:
            self._lock.wait_for(lambda: bool(self._imu) and self._imu[-1][0] >= t_ns, 0.1)
            best = None
            for t, q in reversed(self._imu):
                best = q
                if t <= t_ns:
                    break
            return best

    def _on_image(self, message: Message) -> None:
        meta = codec.decode_frame_meta(message.attachment)
        if meta.frame <= self.last_frame:
            return  # a repeat: already answered
        self.last_frame = meta.frame
        self.frames += 1
        q = self._attitude_at(meta.sim_time_ns)
        with self._lock:
            fix, fresh = self._last_fix, self._fix_fresh
            self._fix_fresh = False
        home = self.vo.home
        start = None
        if fix is not None:
            if fresh:
                self.vo.gps_height(fix[2])
            n, e, _d = geodetic2ned(
                fix[0], fix[1], fix[2], home.lat_deg, home.lon_deg, home.alt_amsl_m
            )
            start = (n, e)
        pos = None if q is None else self.vo.step(message.payload, q, start)
        if pos is None:
            self.errors += 1
            enu = (math.nan, math.nan, math.nan)
        else:
            enu = (float(pos[1]), float(pos[0]), float(-pos[2]))
        # Every frame gets an answer (NaN while the estimator cannot tell): lockstep relies on it.
        payload = codec.dumps(
            {"frame": meta.frame, "sim_time_ns": meta.sim_time_ns, "enu_m": _json_vec(enu)}
        )
        self._out.put(payload)
        self.published += 1


def _json_vec(v: tuple[float, float, float]) -> list[float | None]:
    return [None if math.isnan(c) else c for c in v]


def build_parser() -> argparse.ArgumentParser:
    """The command line of the example localizer."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--name", default="ex", help="estimator name: estimate/<NAME> (default ex)")
    parser.add_argument(
        "--wait", type=float, default=30.0, help="seconds to wait for the simulator (default 30)"
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    add_connection_arguments(parser, serves=False)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the example localizer until SIGINT/SIGTERM."""
    args = build_parser().parse_args(argv)
    try:
        check_chunk("--name", args.name)
        keys = KeySpace(args.vehicle)
        with open_bus(bus_config_from_args(args, serves=False)) as bus:
            loc = Localizer(bus, keys, args.name, wait_s=args.wait)
            if not args.quiet:
                print(f"example_localizer: publishing on {loc.key_out}", flush=True)
            wait_until_signalled()
            if not args.quiet:
                print(
                    f"example_localizer: stopped; {loc.frames} frames, {loc.published} estimates, "
                    f"{loc.vo.lost} lost tracks, {bus.callback_errors[:1] or 'no'} errors",
                    flush=True,
                )
    except AirSitlError as err:
        print(f"example_localizer: error: {err}", file=sys.stderr)
        return err.exit_code
    return 0


if __name__ == "__main__":
    sys.exit(main())
