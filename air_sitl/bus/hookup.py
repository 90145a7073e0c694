"""Attach the bus to one flight: what ``fly`` and ``serve`` call (and nothing else of the bus).

``bus_sinks_from_args(args)`` validates the options and opens the session; the recording code
then calls :meth:`BusHookup.attach` once home, camera and output folder are known, and gets
the sinks to add and the FrameSource to use (remote camera and/or lockstep wrapper).
:meth:`BusHookup.after_flight` collects late estimates and closes the logs;
:meth:`BusHookup.after_archive` fills AIR's Svo columns. Use it as a context manager: the
session closes whatever happens.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from air_sitl.bus.args import BusOptions, bus_options_from_args, gps_denied_from_args
from air_sitl.clock import CAMERA_RATE_HZ, NS_PER_S
from air_sitl.errors import OptionError

if TYPE_CHECKING:
    from air_sitl.bus.estimates import EstimateLog
    from air_sitl.bus.publisher import BusPublisher
    from air_sitl.bus.session import Bus
    from air_sitl.camera.model import CameraModel
    from air_sitl.dataset.writer import ArchiveInfo
    from air_sitl.sinks import FrameSource, Sink
    from air_sitl.state import GeoPoint

GPS_DENIAL_JSON = "gps_denial.json"


@dataclass(slots=True)
class BusHookup:
    """The bus side of one flight (a disabled hookup does nothing but GNSS denial)."""

    options: BusOptions | None
    gps_denied_ns: tuple[tuple[int, int], ...] = ()
    bus: Bus | None = None
    publisher: BusPublisher | None = None
    log: EstimateLog | None = None
    out: Path | None = None
    lockstep_wait_s: list[float] = field(default_factory=list)
    _lockstep: Any = None

    def __enter__(self) -> BusHookup:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    @property
    def needs_camera(self) -> bool:
        """True when the bus wants camera frames (publishing them, or the remote camera)."""
        return self.options is not None and (self.options.publish or self.options.remote_camera)

    def manifest_extra(self) -> dict[str, Any]:
        """What the archive manifest should record: the GNSS denial windows (if any)."""
        if not self.gps_denied_ns:
            return {}
        return {"gps_denied": gps_denial_record(self.gps_denied_ns)}

    def extend_archive_info(self, info: ArchiveInfo) -> ArchiveInfo:
        """The archive's manifest (and resume key) with the GNSS denial windows added."""
        extra = self.manifest_extra()
        if not extra:
            return info
        return dataclasses.replace(
            info, manifest={**info.manifest, **extra}, run_key={**info.run_key, **extra}
        )

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
        self.out = out
        if out is not None and camera is None and self.gps_denied_ns:
            # Without a camera there is no manifest: the windows get a file of their own.
            (out / GPS_DENIAL_JSON).write_text(
                json.dumps(gps_denial_record(self.gps_denied_ns), indent=2) + "\n",
                encoding="utf-8",
            )
        opts = self.options
        if opts is None or self.bus is None:
            return [], frame_source
        from air_sitl.bus.estimates import EstimateLog
        from air_sitl.bus.lockstep import LockstepFrameSource
        from air_sitl.bus.publisher import BusPublisher, FrameLedger, PublishOptions
        from air_sitl.bus.remote_camera import RemoteCamera, RenderSettings

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
                RenderSettings(home=home, camera=camera_fields(camera), seed=seed),
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
        self.log = EstimateLog(self.bus, opts.keys, ledger, out_dir=out, home=home)
        if opts.wait is not None and source is not None:
            publisher = self.publisher
            self._lockstep = LockstepFrameSource(
                source,
                wait=opts.wait,
                publish=publisher.publish_frame,
                ledger=ledger,
                log=self.log,
                image_key=opts.keys.image,
                subscriber_present=lambda: publisher.image_matched,
            )
            source = self._lockstep
        return sinks, source

    def after_flight(self) -> dict[str, Any]:
        """Collect late estimates, close the logs; a summary of what the bus did."""
        summary: dict[str, Any] = {}
        if self.log is not None:
            self.log.settle(quiet_s=0.3, max_s=2.0)
            self.log.close()
            summary["estimates"] = {n: self.log.rows(n) for n in self.log.names()}
            if self.log.rejected:
                summary["estimates_rejected"] = self.log.rejected
                print(
                    f"air-sitl: warning: {self.log.rejected} estimate(s) rejected, first: "
                    f"{self.log.first_error}",
                    file=sys.stderr,
                )
        if self.publisher is not None:
            summary["frames_published"] = self.publisher.frames_published
        if self._lockstep is not None:
            summary["lockstep_wait_wall_s"] = round(self._lockstep.wait_wall_s, 3)
        return summary

    def after_archive(self, archive: Path) -> int:
        """Fill SvoX..SvoZ from ``--svo-columns NAME`` (after the archive is finished)."""
        opts = self.options
        if opts is None or opts.svo_columns is None or self.log is None:
            if self.log is not None and self.log.names():
                from air_sitl.dataset.manifest import refresh_manifest

                refresh_manifest(archive)  # list estimates/ that came after the manifest
            return 0
        from air_sitl.dataset.estimates import fill_svo_columns

        positions = self.log.positions_enu(opts.svo_columns)
        if not positions:
            print(
                f"air-sitl: warning: --svo-columns {opts.svo_columns}: no estimate received",
                file=sys.stderr,
            )
        return fill_svo_columns(archive, positions)

    def close(self) -> None:
        """Close the logs and the session."""
        if self.log is not None:
            self.log.close()
        if self.bus is not None:
            self.bus.close()
            self.bus = None


def bus_sinks_from_args(args: argparse.Namespace) -> BusHookup:
    """Validate the bus and GNSS-denial options and open the session if any option needs it."""
    from air_sitl.bus.session import open_bus

    denied = gps_denied_from_args(args)
    opts = bus_options_from_args(args)
    if not opts.enabled:
        return BusHookup(options=None, gps_denied_ns=denied)
    bus = open_bus(opts.config)
    return BusHookup(options=opts, gps_denied_ns=denied, bus=bus)


def gps_denial_record(windows: tuple[tuple[int, int], ...]) -> list[dict[str, Any]]:
    """The denial windows as the archive records them (an open end is null)."""
    out = []
    for a, b in windows:
        end = None if b >= 2**62 else b
        out.append(
            {
                "start_ns": a,
                "end_ns": end,
                "start_s": a / NS_PER_S,
                "end_s": None if end is None else end / NS_PER_S,
            }
        )
    return out


def camera_fields(camera: CameraModel) -> dict[str, Any]:
    """CameraModel fields as JSON values (what a remote render request carries)."""
    return camera.settings()


def camera_info_of(camera: CameraModel) -> Any:
    """The ``camera/info`` content of a CameraModel."""
    from air_sitl.bus.codec import CameraInfo
    from air_sitl.dataset.camera_info import matrix_to_quat

    r = camera.r_cam_to_body()
    q = matrix_to_quat([[float(r[i][j]) for j in range(3)] for i in range(3)])
    return CameraInfo(
        width_px=camera.width_px,
        height_px=camera.height_px,
        hfov_deg=camera.hfov_deg,
        rate_hz=float(CAMERA_RATE_HZ),
        q_cam_to_body_wxyz=q,
    )
