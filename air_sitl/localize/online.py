"""Online driver: the same method objects on the zenoh bus, one estimate per frame.

Joins the bus like ``bridges/example_localizer.py``: reads ``camera/info`` and the home of
``mission/status`` with a query, reads ``imu``, ``gps``, ``mission/status`` and
``camera/image`` through one subscription (so in the order they were published), and
publishes every frame's answer on ``estimate/<name>`` (no position when the method cannot
tell: lockstep counts it as an answer). Zenoh threads only queue what
arrives; the method runs on the caller's thread, frames in order.

What the observations hold, and how that differs from the offline driver:

- IMU and AHRS: the ``imu`` samples since the previous frame; the attitude at a frame is the
  last sample at or before its exposure (published before the frame, so already there; the
  driver still waits a moment for it);
- GNSS: the last ``gps`` fix at or before the first frame, and no other (``gnss="all"``: every
  new fix, the bus being silent inside denial windows);
- barometer and airspeed: the bus publishes neither, so both are ``None``; the methods then
  hold the height (and deadreckon the ground speed) of the last GNSS fix. An offline run with
  ``bus_inputs=True`` gets exactly these inputs and gives the same estimates (to the
  precision of the archive's CSV numbers).

The run ends on ``stop`` (SIGINT/SIGTERM in the command), when the capture window is over
(``mission/status`` says so and no frame came for :data:`QUIET_S`), or when the simulator
has been silent for ``wait_s`` after the first frame (an error). A simulator whose camera
runs for the whole flight (``fly --nav-aid``: the aid needs frames before and after the
capture window) sends frames outside the window too: the run then ends when the mission is
completed and the frames stopped, or, without an error, when the flight stopped and the
simulator fell silent. The method sees those frames like any other.
"""

from __future__ import annotations

import contextlib
import math
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

import cv2
import numpy as np

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import Bus, Message
from air_sitl.camera.model import CameraModel
from air_sitl.errors import BusError
from air_sitl.frames import quat2euler, quat_conjugate, quat_multiply
from air_sitl.localize import base
from air_sitl.state import GeoPoint, Quat

QUIET_S = 1.0  # after the capture window: no frame for this long ends the run
IMU_WAIT_S = 0.5  # how long a frame waits for the IMU sample of its exposure
GNSS_WAIT_S = 2.0  # how long a frame waits for a first fix (once; GNSS may be denied)
_HALF = math.sqrt(0.5)
_Q_DEFAULT_CAM_TO_BODY: Quat = (_HALF, 0.0, 0.0, _HALF)  # the default mounting: 90 deg yaw

GnssMode = Literal["first", "all"]


@dataclass(frozen=True, slots=True)
class _Frame:
    meta: codec.FrameMeta
    jpeg: bytes


def camera_from_info(info: codec.CameraInfo) -> CameraModel:
    """The camera model ``camera/info`` describes (mounting back to roll/pitch/yaw degrees)."""
    q_mount = quat_multiply(info.q_cam_to_body_wxyz, quat_conjugate(_Q_DEFAULT_CAM_TO_BODY))
    rpy = tuple(round(math.degrees(a), 9) + 0.0 for a in quat2euler(q_mount))
    return CameraModel(
        width_px=info.width_px,
        height_px=info.height_px,
        hfov_deg=info.hfov_deg,
        mount_rpy_deg=(rpy[0], rpy[1], rpy[2]),
    )


def ask(bus: Bus, key: str, wait_s: float) -> Message:
    """Query ``key`` until the simulator answers (it may start after us); BusError after
    ``wait_s`` without an answer."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            return bus.query(key, timeout_s=1.0)
        except BusError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.1)  # the simulator is not up yet: ask again


def feed_latest(bus: Bus, handlers: Mapping[str, Callable[[Message], None]]) -> None:
    """Hand each handler the latest message of its key, when there is one yet (a query each):
    what a localizer joining a running flight starts from."""
    for key, handler in handlers.items():
        with contextlib.suppress(BusError):
            handler(Message(key, bus.query(key, timeout_s=2.0).payload, None))


def subscribe_in_order(
    bus: Bus, keys: KeySpace, handlers: Mapping[str, Callable[[Message], None]]
) -> None:
    """Hand each message of the vehicle's keys to the handler of its key, in the order the
    simulator published them.

    One subscription on ``air/<vehicle>/**``, not one per key: zenoh-python calls each
    subscriber back on a thread of its own, so with one subscriber per key the GNSS fix or
    IMU sample of an exposure can arrive after its frame, from run to run a different one.
    On one subscriber the frame of ``t`` comes after the IMU and GNSS of ``t``, so a frame
    finds all of its inputs (by simulated time) already there. ``handlers`` is read at every
    message: a key added to it later is handed out from then on.
    """

    def dispatch(message: Message) -> None:
        handler = handlers.get(message.key)
        if handler is not None:
            handler(message)

    bus.subscribe(f"{keys.root}/**", dispatch)


def gnss_fix_of(message: Message) -> base.GnssFix | None:
    """The 3D fix a ``gps`` message holds, None without one; BusError naming the key when bad."""
    m = codec.loads(message.payload, message.key)
    with codec.fields_of(message.key, "fix"):
        if int(m.get("fix_type", 3)) < 3:
            return None
        v = m["vel_ned_m_s"]
        return base.GnssFix(
            sim_time_ns=int(m["sim_time_ns"]),
            lat_deg=float(m["lat_deg"]),
            lon_deg=float(m["lon_deg"]),
            alt_amsl_m=float(m["alt_amsl_m"]),
            vel_ned_m_s=(float(v[0]), float(v[1]), float(v[2])),
        )


def _outside_window(
    t_ns: int, capturing: bool | None, opened_ns: int | None, closed_ns: int | None
) -> bool:
    """A frame at ``t_ns`` was taken outside the capture window (before it opened, or after
    the last one closed), as the last status (``capturing``, when it turned on and off) says."""
    if opened_ns is None:
        return capturing is False
    return t_ns < opened_ns or (closed_ns is not None and opened_ns <= closed_ns <= t_ns)


class BusLocalizer:
    """Feeds one method from the bus and publishes its estimates (see the module docstring)."""

    def __init__(
        self,
        bus: Bus,
        keys: KeySpace,
        method: base.Localizer,
        name: str,
        *,
        wait_s: float = 30.0,
        gnss: GnssMode = "first",
        seed: int = 0,
        reference_map: str | None = None,
        reference_date: int | None = None,
    ) -> None:
        self.bus = bus
        self.keys = keys
        self.method = method
        self.key_out = keys.estimate(name)
        self.wait_s = wait_s
        self.gnss_mode = gnss
        self.seed = seed
        self._cond = threading.Condition()
        self._imu: deque[base.ImuReading] = deque(maxlen=4000)
        self._fixes: deque[base.GnssFix] = deque(maxlen=50)
        self._frames: queue.Queue[_Frame] = queue.Queue()
        self._capturing: bool | None = None
        self._status_t_ns = -1
        self._completed = False
        self._window_opened_ns: int | None = None  # when ``capturing`` last turned true
        self._window_closed_ns: int | None = None  # and false
        self._camera_kept_on = False  # a frame came from outside the capture window
        self._last_heard = time.monotonic()
        self.frames = 0
        self.estimated = 0
        self.last_frame = -1
        self._last_answer: bytes | None = None  # the estimate of last_frame, as published
        self._last_t_ns: int | None = None
        self._last_fix_t_ns: int | None = None
        self.step_s = 0.0  # wall time spent in the method

        # Read in publishing order: a frame finds the IMU and GNSS of its step already there.
        self._handlers: dict[str, Callable[[Message], None]] = {
            keys.imu: self._on_imu,
            keys.gps: self._on_gps,
            keys.mission_status: self._on_status,
            keys.image: self._on_image,  # queued until :meth:`run`
        }
        subscribe_in_order(bus, keys, self._handlers)
        info = codec.decode_camera_info(ask(bus, keys.info, wait_s).payload)
        status = ask(bus, keys.mission_status, wait_s)
        self._on_status(status)
        home = codec.loads(status.payload, keys.mission_status).get("home")
        if not isinstance(home, dict):
            msg = f"{keys.mission_status}: no home in the status"
            raise BusError(msg)
        self.context = base.LocalizerContext(
            home=GeoPoint(
                lat_deg=float(home["lat_deg"]),
                lon_deg=float(home["lon_deg"]),
                alt_amsl_m=float(home["alt_amsl_m"]),
            ),
            camera=camera_from_info(info),
            frame_rate_hz=info.rate_hz,
            seed=seed,
            reference_map=reference_map,
            reference_date=reference_date,
            extras={"bus": keys.root},
        )
        method.reset(self.context)
        feed_latest(bus, {keys.gps: self._on_gps, keys.imu: self._on_imu})
        self._out = bus.publisher(self.key_out, encoding=codec.JSON_ENCODING, block=True)

    # -- zenoh threads: decode and queue, nothing else ------------------------------------

    def _on_imu(self, message: Message) -> None:
        reading = codec.decode_imu(message.payload)
        with self._cond:
            if not self._imu or self._imu[-1].sim_time_ns < reading.sim_time_ns:
                self._imu.append(reading)
            self._last_heard = time.monotonic()
            self._cond.notify_all()

    def _on_gps(self, message: Message) -> None:
        fix = gnss_fix_of(message)
        if fix is None:
            return
        with self._cond:
            if not self._fixes or self._fixes[-1].sim_time_ns < fix.sim_time_ns:
                self._fixes.append(fix)
                self._cond.notify_all()

    def _on_status(self, message: Message) -> None:
        m = codec.loads(message.payload, message.key)
        with self._cond:
            t = int(m.get("sim_time_ns", 0))
            if t >= self._status_t_ns:
                self._status_t_ns = t
                capturing = bool(m.get("capturing"))
                if capturing != bool(self._capturing):
                    if capturing:
                        self._window_opened_ns = t
                    else:
                        self._window_closed_ns = t
                self._capturing = capturing
                self._completed = bool(m.get("mission_completed"))
            self._last_heard = time.monotonic()

    def _on_image(self, message: Message) -> None:
        self._frames.put(_Frame(codec.decode_frame_meta(message.attachment), message.payload))

    # -- the caller's thread ----------------------------------------------------------------

    def _capture_over(self) -> bool:
        with self._cond:
            if self._last_t_ns is None:
                return False
            if self._completed:
                return True
            if self._camera_kept_on:
                return False  # frames outside the window: the flight decides the end
            return self._capturing is False and self._status_t_ns > self._last_t_ns

    def run(self, stop: threading.Event) -> None:
        """Answer frames until ``stop``, the end of the capture window, or a silent simulator."""
        quiet_since = time.monotonic()
        while not stop.is_set():
            try:
                frame: _Frame | None = self._frames.get(timeout=0.1)
            except queue.Empty:
                frame = None
            if frame is not None:
                self.handle(frame.meta, frame.jpeg)
                quiet_since = time.monotonic()
                continue
            now = time.monotonic()
            if self._capture_over() and now - quiet_since >= QUIET_S:
                return
            with self._cond:
                silent = now - self._last_heard
            if self.frames and silent > self.wait_s:
                if self._camera_kept_on:
                    return  # the flight stopped with the camera on (no mission completion)
                msg = f"{self.keys.root}: the simulator has been silent for {silent:.0f} s"
                raise BusError(msg)

    def observation(self, meta: codec.FrameMeta, jpeg: bytes) -> base.Observation | None:
        """The observation of one frame from what the bus delivered (None: no attitude yet)."""
        t = meta.sim_time_ns
        with self._cond:
            self._cond.wait_for(
                lambda: bool(self._imu) and self._imu[-1].sim_time_ns >= t, IMU_WAIT_S
            )
            if self._last_fix_t_ns is None:
                # No fix given yet: the fix of this exposure travels on its own key and may come
                # after the frame (the first frame of an air start is at t = 0, like a fix).
                self._cond.wait_for(
                    lambda: any(f.sim_time_ns <= t for f in self._fixes), GNSS_WAIT_S
                )
            prev = self._last_t_ns
            readings = tuple(
                s
                for s in self._imu
                if s.sim_time_ns <= t and (prev is None or s.sim_time_ns > prev)
            )
            at = [s for s in self._imu if s.sim_time_ns <= t]
            fixes = [f for f in self._fixes if f.sim_time_ns <= t]
        if not at:
            return None
        if prev is None and len(readings) > 1:
            readings = readings[-1:]  # the first frame: only the sample of its exposure
        fix = fixes[-1] if fixes else None
        if fix is not None and (
            # "first": one fix, the first there is (at the first frame unless it came late)
            (self.gnss_mode == "first" and self._last_fix_t_ns is not None)
            or (self._last_fix_t_ns is not None and fix.sim_time_ns <= self._last_fix_t_ns)
        ):
            fix = None
        if fix is not None:
            self._last_fix_t_ns = fix.sim_time_ns
        image = None
        if self.method.needs_image:
            decoded = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
            image = None if decoded is None else np.asarray(decoded, dtype=np.uint8)
        return base.Observation(
            frame=meta.frame,
            sim_time_ns=t,
            image_bgr=image,
            imu=readings,
            q_ahrs_body_to_ned_wxyz=at[-1].q_ahrs_body_to_ned_wxyz,
            airspeed_m_s=None,
            baro_alt_rel_m=None,
            gnss=fix,
            jpeg=jpeg,
        )

    def handle(self, meta: codec.FrameMeta, jpeg: bytes) -> base.Estimate | None:
        """Localize one frame and publish the answer (every frame gets one)."""
        if meta.frame <= self.last_frame:
            if meta.frame != 0 or self.last_frame == 0:
                if meta.frame == self.last_frame and self._last_answer is not None:
                    # The simulator offers the frame again (lockstep after a lost connection:
                    # our answer may not have reached it): the same answer again.
                    self._out.put(self._last_answer)
                return None  # a repeat: already answered
            self._restart()  # frame 0 again after others: a new capture window
        self.frames += 1
        obs = self.observation(meta, jpeg)
        est = None
        if obs is not None:
            start = time.perf_counter()
            est = self.method.step(obs)
            self.step_s += time.perf_counter() - start
        self.last_frame = meta.frame
        self._last_t_ns = meta.sim_time_ns
        with self._cond:
            if _outside_window(
                meta.sim_time_ns, self._capturing, self._window_opened_ns, self._window_closed_ns
            ):
                self._camera_kept_on = True
        enu = None if est is None else est.enu_m
        if enu is not None and all(math.isfinite(c) for c in enu):
            self.estimated += 1
        else:
            enu = None
        self._last_answer = codec.encode_estimate(
            frame=meta.frame,
            sim_time_ns=meta.sim_time_ns,
            enu_m=enu,
            q_body_to_ned_wxyz=None if est is None else est.q_body_to_ned_wxyz,
            cov_enu_m2=None if est is None or enu is None else est.cov_enu_m2,
            fix=None if est is None else est.fix,
        )
        self._out.put(self._last_answer)
        return est

    def _restart(self) -> None:
        self.method.reset(self.context)
        self.last_frame = -1
        self._last_answer = None
        self._last_t_ns = None
        self._last_fix_t_ns = None
        self._camera_kept_on = False
        self.frames = 0  # the counts of the closing line are the new window's
        self.estimated = 0
        self.step_s = 0.0

    def summary(self) -> dict[str, Any]:
        """Counts for the closing line."""
        rate = self.frames / self.step_s if self.step_s > 0 else None
        return {
            "frames": self.frames,
            "estimated": self.estimated,
            "method_frames_per_s": rate,
            "callback_errors": list(self.bus.callback_errors[:3]),
        }
