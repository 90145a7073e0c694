#!/usr/bin/env python3
"""An external localization process on the bus: the package's ``vo`` method, hand-wired.

The pattern every estimator follows: join the bus, read ``camera/info`` and the latest
``mission/status`` (home) and ``gps`` with a query, subscribe to the vehicle's keys, publish
one estimate per frame on ``air/<vehicle>/estimate/<name>`` (no position when it cannot tell:
lockstep counts that as an answer too).

It reads the bus in publishing order (``subscribe_in_order``: one subscription on
``air/<vehicle>/**``, not one per key, whose callbacks zenoh-python runs on threads of their
own): a frame comes after the IMU and GNSS of its own step, so a lockstep run
(``fly --wait-for NAME``) gives the same estimates every time.

The method is :class:`air_sitl.localize.vo.VisualOdometry` (attitude-compensated
frame-to-frame VO), given the GNSS fix at the first frame only, then pure odometry: it
drifts. ``air-sitl localize --bus --method vo`` runs the same method with a complete driver
(IMU history, capture end, any registered method); this file shows the bus contract in full.

Run: ``python bridges/example_localizer.py --name ex`` next to ``air-sitl fly --zenoh ...``.
It exits (0) when the vehicle's mission completes (``mission/status``), or on Ctrl-C; a
flight that never completes (``--max-sim-time``, a crash) leaves it waiting for the next one.
"""

from __future__ import annotations

import argparse
import sys
import threading
from collections import deque
from collections.abc import Callable

from air_sitl.bus import codec
from air_sitl.bus.args import add_connection_arguments, bus_config_from_args
from air_sitl.bus.keys import KeySpace, check_chunk
from air_sitl.bus.session import Bus, Message, open_bus
from air_sitl.bus.signals import wait_until_signalled
from air_sitl.errors import AirSitlError, BusError
from air_sitl.localize.base import GnssFix, LocalizerContext, Observation
from air_sitl.localize.online import (
    ask,
    camera_from_info,
    feed_latest,
    gnss_fix_of,
    subscribe_in_order,
)
from air_sitl.localize.vo import VisualOdometry
from air_sitl.state import GeoPoint, Quat


class Localizer:
    """Bus side of the example: subscriptions, the IMU history, and publishing estimates."""

    def __init__(self, bus: Bus, keys: KeySpace, name: str, *, wait_s: float) -> None:
        self.bus = bus
        self.key_out = keys.estimate(name)
        self._lock = threading.Lock()
        self._imu: deque[tuple[int, Quat]] = deque(maxlen=2000)
        self._fix: GnssFix | None = None
        self.frames = self.published = 0
        self.last_frame = -1
        self._last_answer: bytes | None = None  # the estimate of last_frame, as published
        self.flight_over = threading.Event()  # the vehicle's mission completed
        self._handlers: dict[str, Callable[[Message], None]] = {
            keys.imu: self._on_imu,
            keys.gps: self._on_gps,
            keys.mission_status: self._on_status,
        }
        subscribe_in_order(bus, keys, self._handlers)
        info = codec.decode_camera_info(ask(bus, keys.info, wait_s).payload)
        status = codec.loads(ask(bus, keys.mission_status, wait_s).payload, keys.mission_status)
        h = status.get("home")
        if not isinstance(h, dict):
            msg = f"{keys.mission_status}: no home in the status"
            raise BusError(msg)
        home = GeoPoint(lat_deg=h["lat_deg"], lon_deg=h["lon_deg"], alt_amsl_m=h["alt_amsl_m"])
        self.vo = VisualOdometry()
        self.vo.reset(LocalizerContext(home=home, camera=camera_from_info(info)))
        feed_latest(bus, {keys.gps: self._on_gps, keys.imu: self._on_imu})
        self._out = bus.publisher(self.key_out, encoding=codec.JSON_ENCODING, block=True)
        self._handlers[keys.image] = self._on_image  # frames only once ready to answer

    def _on_imu(self, message: Message) -> None:
        imu = codec.decode_imu(message.payload)
        with self._lock:
            self._imu.append((imu.sim_time_ns, imu.q_ahrs_body_to_ned_wxyz))

    def _on_status(self, message: Message) -> None:
        """The mission completed: every frame came before this status (publishing order)."""
        if codec.loads(message.payload, message.key).get("mission_completed"):
            self.flight_over.set()

    def _on_gps(self, message: Message) -> None:
        fix = gnss_fix_of(message)
        if fix is None:
            return  # no 3D fix: keep the last one
        with self._lock:
            self._fix = fix

    def _attitude_at(self, t_ns: int) -> Quat | None:
        """The AHRS attitude at the exposure (the IMU sample of that step came before the
        frame on the same subscription)."""
        with self._lock:
            best = None
            for t, q in reversed(self._imu):
                best = q
                if t <= t_ns:
                    break
            return best

    def _on_image(self, message: Message) -> None:
        meta = codec.decode_frame_meta(message.attachment)
        if meta.frame <= self.last_frame:
            if meta.frame == self.last_frame and self._last_answer is not None:
                self._out.put(self._last_answer)  # offered again: our answer may have been lost
            return  # a repeat: already answered
        first = self.last_frame < 0
        self.last_frame = meta.frame
        self.frames += 1
        q = self._attitude_at(meta.sim_time_ns)
        with self._lock:
            fix = self._fix if first else None  # GNSS at the first frame only
        est = None
        if q is not None:
            obs = Observation(
                frame=meta.frame,
                sim_time_ns=meta.sim_time_ns,
                image_bgr=None,
                imu=(),
                q_ahrs_body_to_ned_wxyz=q,
                airspeed_m_s=None,
                baro_alt_rel_m=None,  # no barometer on the bus: the fix's height is held
                gnss=fix,
                jpeg=message.payload,
            )
            est = self.vo.step(obs)
        # Every frame gets an answer (no position while the estimator cannot tell).
        enu = None if est is None else est.enu_m
        self._last_answer = codec.encode_estimate(
            frame=meta.frame, sim_time_ns=meta.sim_time_ns, enu_m=enu
        )
        self._out.put(self._last_answer)
        self.published += 1


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
    """Run the example localizer until the vehicle's mission completes, or SIGINT/SIGTERM."""
    args = build_parser().parse_args(argv)
    try:
        check_chunk("--name", args.name)
        keys = KeySpace(args.vehicle)
        with open_bus(bus_config_from_args(args, serves=False)) as bus:
            loc = Localizer(bus, keys, args.name, wait_s=args.wait)
            if not args.quiet:
                print(f"example_localizer: publishing on {loc.key_out}", flush=True)
            wait_until_signalled(loc.flight_over)
            if not args.quiet:
                why = "the flight ended" if loc.flight_over.is_set() else "stopped"
                print(
                    f"example_localizer: {why}; {loc.frames} frames, {loc.published} estimates, "
                    f"{loc.vo.lost} lost tracks, {bus.callback_errors[:1] or 'no'} errors",
                    flush=True,
                )
    except AirSitlError as err:
        print(f"example_localizer: error: {err}", file=sys.stderr)
        return err.exit_code
    return 0


if __name__ == "__main__":
    sys.exit(main())
