"""Attach the bus to one flight: what ``fly`` and ``serve`` call (and nothing else of the bus).

``bus_sinks_from_args(args)`` validates the options and opens the session; the recording code
then calls :meth:`BusHookup.attach` once home, camera and output folder are known, and gets
the sinks to add and the FrameSource to use (remote camera and/or lockstep wrapper).
:meth:`BusHookup.after_flight` collects late estimates and closes the logs; the recording then
takes what it needs into the archive (:meth:`BusHookup.svo_positions`). The bus only publishes
and collects estimates: it knows nothing of archives. Use it as a context manager: the session
closes whatever happens.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from air_sitl.bus.aid_feed import BusAidFeed
from air_sitl.bus.args import BusOptions, bus_options_from_args
from air_sitl.bus.codec import CameraInfo
from air_sitl.bus.estimates import EstimateLog
from air_sitl.bus.estimator_watch import EstimatorWatch, estimate_summary, estimate_warnings
from air_sitl.bus.lockstep import LockstepFrameSource
from air_sitl.bus.publisher import BusPublisher, FrameLedger, PublishOptions
from air_sitl.bus.remote_camera import RemoteCamera, RenderSettings
from air_sitl.bus.ros2.view import Ros2Estimates, Ros2View, open_node
from air_sitl.bus.session import Bus, open_bus
from air_sitl.camera.info import q_cam_to_body_wxyz
from air_sitl.camera.model import CameraModel
from air_sitl.clock import CAMERA_RATE_HZ
from air_sitl.closeable import Closeable
from air_sitl.errors import OptionError
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import CameraFrame, GeoPoint, Vec3


@dataclass(slots=True)
class BusHookup(Closeable):
    """The bus side of one flight (a disabled hookup does nothing)."""

    options: BusOptions | None
    bus: Bus | None = None
    publisher: BusPublisher | None = None
    log: EstimateLog | None = None
    ros2: Ros2View | None = None
    ros2_estimates: Ros2Estimates | None = None
    _lockstep: LockstepFrameSource | None = None
    _watch: EstimatorWatch | None = None

    @property
    def needs_camera(self) -> bool:
        """True when the bus wants camera frames (publishing them, or the remote camera)."""
        return self.options is not None and (self.options.publish or self.options.remote_camera)

    def attach(
        self,
        *,
        home: GeoPoint,
        out: Path | None,
        camera: CameraModel | None,
        seed: int,
        frame_source: FrameSource | None,
    ) -> tuple[list[Sink], FrameSource | None]:
        """Sinks to add to the flight, and the FrameSource to use instead of ``frame_source``."""
        opts = self.options
        if opts is None or self.bus is None:
            return [], frame_source
        source = frame_source
        if opts.remote_camera:
            if camera is None:
                msg = "--camera remote: the flight has no camera (drop --no-camera)"
                raise OptionError(msg)
            if source is not None:
                source.close()
            source = RemoteCamera(
                self.bus,
                opts.keys,
                RenderSettings(home=home, camera=camera.settings(), seed=seed),
                timeout_s=opts.wait_timeout_s,
            )
        sinks: list[Sink] = []
        if not opts.publish:
            return sinks, source
        if opts.wait is not None and source is None:
            msg = f"--wait-for {opts.wait.name}: lockstep needs camera frames (drop --no-camera)"
            raise OptionError(msg)
        ledger = FrameLedger()
        self.publisher = BusPublisher(
            self.bus,
            PublishOptions(
                keys=opts.keys,
                publish_truth=opts.publish_truth,
                imu_rate_hz=opts.imu_rate_hz,
                home=home,
                camera_info=None if camera is None else camera_info_of(camera),
                block_frames=opts.wait is not None,
            ),
            ledger,
        )
        sinks.append(self.publisher)
        self.log = EstimateLog(
            self.bus, opts.keys, ledger, out_dir=out, home=home, max_names=opts.max_estimate_names
        )
        if opts.expected:
            self._watch = EstimatorWatch(self.log, opts.expected, sys.stderr)
        publish_frame, subscriber_present = self._attach_ros2(opts, camera)
        if opts.wait is not None and source is not None:
            publisher = self.publisher
            self._lockstep = LockstepFrameSource(
                source,
                wait=opts.wait,
                publish=publish_frame,
                ledger=ledger,
                log=self.log,
                image_key=opts.keys.image,
                subscriber_present=subscriber_present,
                reoffer=publisher.reoffer_frame,
            )
            source = self._lockstep
            publisher.gate = self._lockstep.wait_for_consumer
        if self.ros2 is not None:
            sinks.append(self.ros2)
        return sinks, source

    def _attach_ros2(
        self, opts: BusOptions, camera: CameraModel | None
    ) -> tuple[Callable[[CameraFrame], None], Callable[[], bool]]:
        """The ROS 2 view (``--ros2``); how lockstep publishes a frame and sees a consumer."""
        publisher = self.publisher
        assert publisher is not None and self.bus is not None
        if opts.ros2 is None:
            return publisher.publish_frame, lambda: publisher.image_matched
        node = open_node(self.bus, opts.ros2, opts.keys)
        view = Ros2View(
            node,
            opts.keys,
            camera=camera,
            publish_truth=opts.publish_truth,
            imu_rate_hz=opts.imu_rate_hz,
            block_frames=opts.wait is not None,
        )
        names = [n for n in (opts.svo_columns, opts.wait and opts.wait.name) if n]
        self.ros2, self.ros2_estimates = view, Ros2Estimates(node, opts.keys, names)

        def publish_both(frame: CameraFrame) -> None:
            publisher.publish_frame(frame)
            view.publish_frame(frame)

        return publish_both, lambda: publisher.image_matched or view.image_matched

    def after_flight(self) -> dict[str, Any]:
        """Collect late estimates, close the logs; a summary of what the bus did (and one
        warning line per thing the user should know: rejected estimates, an awaited estimator
        never heard, frames it left unanswered)."""
        summary: dict[str, Any] = {}
        if self._watch is not None:
            self._watch.stop()
        log = self.log
        if log is not None:
            log.settle(quiet_s=0.3, max_s=2.0)
            log.close()
            summary.update(estimate_summary(log, self.expected))
            for line in estimate_warnings(summary, log):
                print(f"air-sitl: warning: {line}", file=sys.stderr)
        if self.bus is not None and self.bus.callback_errors:
            errors = self.bus.callback_errors
            summary["bus_callback_errors"] = len(errors)
            print(
                f"air-sitl: warning: {len(errors)} error(s) in bus callbacks, first: {errors[0]}",
                file=sys.stderr,
            )
        if self.publisher is not None:
            summary["frames_published"] = self.publisher.frames_published
            if self.publisher.frames_reoffered:
                summary["frames_reoffered"] = self.publisher.frames_reoffered
        if self.ros2 is not None and self.ros2_estimates is not None:
            est = self.ros2_estimates
            summary["ros2"] = {
                "node": self.ros2.node.name,
                "frames_published": self.ros2.frames_published,
                "estimates_accepted": est.accepted,
                "estimates_rejected": est.rejected,
            }
            if est.rejected:
                print(
                    f"air-sitl: warning: {est.rejected} ROS 2 estimate sample(s) ignored, "
                    f"first: {est.first_error}",
                    file=sys.stderr,
                )
        if self._lockstep is not None:
            summary["lockstep_wait_wall_s"] = round(self._lockstep.wait_wall_s, 3)
        return summary

    @property
    def expected(self) -> tuple[str, ...]:
        """The estimators this flight relies on (``--wait-for``, ``--svo-columns``,
        ``--nav-aid``)."""
        return () if self.options is None else self.options.expected

    def nav_aid_feed(self, name: str) -> BusAidFeed | None:
        """The estimates of ``name`` for the onboard filter (``--nav-aid NAME``); None when
        the bus collects no estimates. Deterministic in lockstep with the same name."""
        if self.log is None or self.options is None:
            return None
        if self.ros2_estimates is not None:
            self.ros2_estimates.announce(name)
        wait = self.options.wait
        lag = wait.max_lag if wait is not None and wait.name == name else None
        ledger = self.log.ledger
        feed = BusAidFeed(name, lockstep_lag=lag, time_of=lambda f: ledger.lookup(f, None)[1])
        self.log.listeners.append(feed.on_estimate)
        return feed

    @property
    def svo_columns(self) -> str | None:
        """``--svo-columns NAME``: the estimator whose positions fill AIR's SvoX..SvoZ."""
        return None if self.options is None else self.options.svo_columns

    def estimate_names(self) -> list[str]:
        """The estimators heard from (each logged as ``estimates/<name>.csv``)."""
        return [] if self.log is None else self.log.names()

    def svo_positions(self) -> dict[int, Vec3] | None:
        """ENU positions by frame of the ``--svo-columns`` estimator; None without the option."""
        if self.svo_columns is None or self.log is None:
            return None
        return self.log.positions_enu(self.svo_columns)

    def close(self) -> None:
        """Close the logs and the session."""
        if self._watch is not None:
            self._watch.stop()
        if self.log is not None:
            self.log.close()
        if self.bus is not None:
            self.bus.close()
            self.bus = None


def bus_sinks_from_args(args: argparse.Namespace) -> BusHookup:
    """Validate the bus options and open the session if any option needs it."""
    opts = bus_options_from_args(args)
    if not opts.enabled:
        return BusHookup(options=None)
    return BusHookup(options=opts, bus=open_bus(opts.config))


def camera_info_of(camera: CameraModel) -> CameraInfo:
    """The ``camera/info`` content of a CameraModel."""
    return CameraInfo(
        width_px=camera.width_px,
        height_px=camera.height_px,
        hfov_deg=camera.hfov_deg,
        rate_hz=float(CAMERA_RATE_HZ),
        q_cam_to_body_wxyz=q_cam_to_body_wxyz(camera),
    )
