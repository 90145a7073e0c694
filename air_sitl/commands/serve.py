"""``air-sitl serve``: a PX4-like vehicle on MAVLink links, flown by ground stations.

The vehicle starts on the ground at home, disarmed; clients (QGroundControl, MAVSDK, MAVProxy,
pymavlink) connect, upload a mission, arm and start it. It runs until SIGINT or SIGTERM.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import math
import queue
import signal
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from air_sitl.autopilot.autopilot import Autopilot
    from air_sitl.camera.model import CameraModel
    from air_sitl.dataset.writer import DatasetWriter
    from air_sitl.options import FlightOptions
    from air_sitl.runner import Flight, InboxItem
    from air_sitl.sinks import FlightResult, FrameSource, Sink
    from air_sitl.state import CameraFrame, GeoPoint, SimSample

HELP = "run a PX4-like MAVLink vehicle that ground stations connect to, upload missions to and fly"
DEFAULT_HOME = (47.397742, 8.545594, 488.0)  # PX4 SITL's default home (Zurich)
FOREVER_NS = 2**62


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``serve``."""
    from air_sitl.bus.args import add_bus_arguments
    from air_sitl.camera.options import add_camera_arguments, add_map_arguments
    from air_sitl.options import add_flight_arguments

    parser.add_argument(
        "--mavlink",
        action="append",
        metavar="URL",
        help="udpout:HOST:PORT, udpin:HOST:PORT or tcpin:HOST:PORT; repeatable "
        "(default: udpout:127.0.0.1:14550 and udpout:127.0.0.1:14540, as PX4 SITL)",
    )
    parser.add_argument("--plan", default=None, help="preload this .plan as if uploaded")
    parser.add_argument(
        "--home", default=None, help="LAT,LON,ALT_AMSL (default: the plan's home, else PX4's)"
    )
    parser.add_argument(
        "--out",
        default=None,
        help="record each capture window (camera frames, AIR archive) into OUT/<n>/",
    )
    parser.add_argument(
        "--signing-key", default=None, metavar="HEX|@FILE", help="MAVLink 2 signing key"
    )
    parser.add_argument("--quiet", action="store_true", help="print only errors")
    add_flight_arguments(parser, default_speed=1.0)
    add_map_arguments(parser)
    add_camera_arguments(parser)
    add_bus_arguments(parser)


def parse_home(text: str) -> GeoPoint:
    """``LAT,LON,ALT`` in degrees and metres AMSL."""
    from air_sitl.errors import OptionError
    from air_sitl.state import GeoPoint

    parts = text.split(",")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        msg = f"--home {text!r}: expected LAT,LON,ALT_AMSL (for example 47.3977,8.5456,488)"
        raise OptionError(msg) from None
    if not (math.isfinite(lat + lon + alt) and -90 <= lat <= 90 and -180 <= lon <= 180):
        msg = f"--home {text!r}: latitude must be in [-90, 90], longitude in [-180, 180]"
        raise OptionError(msg)
    return GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)


def run(args: argparse.Namespace) -> int:
    """Serve until interrupted; exit 0 on SIGINT/SIGTERM."""
    from air_sitl.bus.hookup import bus_sinks_from_args
    from air_sitl.errors import OptionError
    from air_sitl.mavlink.codec import load_signing_key
    from air_sitl.mavlink.links import DEFAULT_LINKS, parse_link
    from air_sitl.mavlink.vehicle import EndpointOptions, Job, VehicleEndpoint
    from air_sitl.mission.items import Mission
    from air_sitl.mission.plan_file import load_mission
    from air_sitl.options import flight_options_from_args
    from air_sitl.runner import assemble_flight, home_of
    from air_sitl.state import GeoPoint

    options = flight_options_from_args(args)
    if options.air_start:
        msg = "--air-start: serve starts on the ground; upload, arm and start from a client"
        raise OptionError(msg)
    specs = [parse_link(url) for url in (args.mavlink or DEFAULT_LINKS)]
    for spec in specs:
        if not spec.loopback:
            print(
                f"air-sitl serve: warning: {spec} is reachable from other machines",
                file=sys.stderr,
            )
    key = load_signing_key(args.signing_key) if args.signing_key else None
    if args.plan:
        mission = load_mission(Path(args.plan))
        home = parse_home(args.home) if args.home else home_of(mission)
    else:
        mission = Mission(items=(), source="serve")
        lat, lon, alt = DEFAULT_HOME
        home = (
            parse_home(args.home)
            if args.home
            else GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
        )

    inbox: queue.SimpleQueue[InboxItem] = queue.SimpleQueue()

    def post(job: Job) -> None:
        def on_flight(flight: Flight) -> None:
            job(flight.autopilot)

        inbox.put(on_flight)

    endpoint = VehicleEndpoint(
        specs, home=home, mission=mission, post=post, options=EndpointOptions(signing_key=key)
    )
    hookup = bus_sinks_from_args(args)
    try:
        addresses = endpoint.open()
        sinks: list[Sink] = [endpoint.sink]
        camera: FrameSource | None = None
        recorder = None
        if args.out:
            from air_sitl.camera.options import camera_bridge_from_args, camera_from_args

            camera = camera_bridge_from_args(args, home, mission.name, seed=options.seed)
            model = camera_from_args(args)
            recorder = CaptureRecorder(
                Path(args.out),
                model,
                home,
                _manifest(args, options, model, home) | hookup.manifest_extra(),
            )
            sinks.append(recorder)
        if camera is None and hookup.needs_camera:
            from air_sitl.camera.options import camera_bridge_from_args

            camera = camera_bridge_from_args(args, home, mission.name, seed=options.seed)
        if hookup.options is not None or hookup.gps_denied_ns:
            from air_sitl.camera.options import camera_from_args

            bus_sinks, camera = hookup.attach(
                home=home,
                out=Path(args.out) if args.out else None,
                camera=camera_from_args(args) if camera is not None else None,
                seed=options.seed,
                frame_source=camera,
            )
            sinks.extend(bus_sinks)
        flight, home, _initial = assemble_flight(
            mission, options, sinks=sinks, camera=camera, home=home, auto_start=False
        )
        flight.sensors.gps_denied_ns = hookup.gps_denied_ns
        endpoint.attach(flight.autopilot, flight.autopilot.params)
        if recorder is not None:
            recorder.autopilot = flight.autopilot
        endpoint.start()
        if not args.quiet:
            links = ", ".join(
                f"{spec} (local {host}:{port})"
                for spec, (host, port) in zip(specs, addresses, strict=True)
            )
            print(
                f"air-sitl serve: vehicle ready at {home.lat_deg:.7f},{home.lon_deg:.7f},"
                f"{home.alt_amsl_m:.1f} speed {options.speed:g}; links: {links}",
                flush=True,
            )
        stop = threading.Event()

        def on_signal(signum: int, _frame: FrameType | None) -> None:
            stop.set()

        previous = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
        try:
            flight.run(
                stop=lambda _sample: stop.is_set(),
                max_sim_time_ns=_max_sim_ns(args, options.max_sim_time_s),
                inbox=inbox,
            )
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
    finally:
        endpoint.close()
        hookup.close()
    if not args.quiet:
        c = endpoint.counters
        print(
            f"air-sitl serve: stopped; {c.messages} messages received, {c.dropped} frames "
            f"dropped ({c.parse_errors} parse errors, {c.unknown_ids} unknown, "
            f"{c.signature_rejected} signature rejected)",
            flush=True,
        )
    return 0


def _max_sim_ns(args: argparse.Namespace, max_sim_time_s: float) -> int:
    """Serve runs forever unless --max-sim-time was given explicitly."""
    if str(args.max_sim_time) == "14400":
        return FOREVER_NS
    return int(max_sim_time_s * 1e9)


def _manifest(
    args: argparse.Namespace, options: FlightOptions, camera: CameraModel, home: GeoPoint
) -> dict[str, Any]:
    """What every archive of this serve run records about its inputs."""
    from air_sitl.recording import manifest_inputs

    return manifest_inputs(options, camera, home) | {
        "map": args.map or "default",
        "recorded_by": "air-sitl serve",
    }


@dataclass(slots=True)
class _Window:
    """One capture window being recorded."""

    folder: Path
    writer: DatasetWriter
    first_tick: int
    end_tick: int | None = None  # set when capture stops
    next_frame: int = 0
    distance_m: float = 0.0
    last_ne: tuple[float, float] | None = None
    start_ns: int = 0


class CaptureRecorder:
    """A Sink that opens a new AIR archive ``ROOT/<n>/`` for each capture window.

    Frames keep their flight-wide tick index in the runner; each archive renumbers them from 0.
    A window's archive is sealed once its last frame arrived (frames lag behind the samples).
    A write error abandons that archive with a warning: the vehicle keeps flying.
    """

    def __init__(
        self, root: Path, camera: CameraModel, home: GeoPoint, manifest: dict[str, Any]
    ) -> None:
        self.root = root
        from air_sitl.recording import camera_yaml_for

        self.camera_yaml = camera_yaml_for(camera)
        self.home = home
        self.manifest = manifest
        self.autopilot: Autopilot | None = None
        self.archives: list[Path] = []
        self._ticks = 0
        self._window: _Window | None = None
        self._last_sample: SimSample | None = None
        self._failed = False

    def _next_folder(self) -> Path:
        used = [int(p.name) for p in self.root.glob("*") if p.name.isdigit()]
        return self.root / str(max(used, default=0) + 1)

    def _open(self, sample: SimSample) -> None:
        from air_sitl.dataset.writer import ArchiveInfo, DatasetWriter
        from air_sitl.mission.plan_file import plan_text

        mission = self.autopilot.mission if self.autopilot is not None else None
        name = (mission.name if mission is not None else "") or "serve"
        text = plan_text(mission) if mission is not None and mission.items else "{}\n"
        folder = self._next_folder()
        info = ArchiveInfo(
            scenario=name,
            camera_yaml=self.camera_yaml,
            plan_name=f"{name}.plan",
            plan_text=text,
            manifest=self.manifest,
        )
        writer = DatasetWriter(folder, info)
        self._window = _Window(folder, writer, self._ticks, start_ns=sample.state.sim_time_ns)
        print(f"air-sitl serve: recording into {folder}", flush=True)

    def on_sample(self, sample: SimSample) -> None:
        """Open, feed and close windows following ``capturing``."""
        from air_sitl.clock import CAMERA_PERIOD_NS
        from air_sitl.errors import AirSitlError

        self._last_sample = sample
        capturing = sample.autopilot.capturing
        try:
            if not capturing:
                self._failed = False
            if (
                capturing
                and not self._failed
                and (self._window is None or self._window.end_tick is not None)
            ):
                if self._window is not None:
                    self._seal()  # frames of the previous window never came: seal it as is
                self._open(sample)
            w = self._window
            if w is not None and w.end_tick is None:
                if capturing:
                    w.writer.on_sample(sample)
                    n, e = sample.state.pos_ned_m[0], sample.state.pos_ned_m[1]
                    if w.last_ne is not None:
                        w.distance_m += math.hypot(n - w.last_ne[0], e - w.last_ne[1])
                    w.last_ne = (n, e)
                else:
                    w.end_tick = self._ticks
                    if w.next_frame >= w.end_tick - w.first_tick:
                        self._seal()
        except AirSitlError as err:
            self._abandon(err)
        if capturing and sample.state.sim_time_ns % CAMERA_PERIOD_NS == 0:
            self._ticks += 1

    def on_frame(self, frame: CameraFrame) -> None:
        """Renumber the frame within its window and hand it to that window's writer."""
        from air_sitl.errors import AirSitlError

        w = self._window
        if w is None or frame.index < w.first_tick:
            return
        try:
            w.writer.on_frame(dataclasses.replace(frame, index=frame.index - w.first_tick))
            w.next_frame = frame.index - w.first_tick + 1
            if w.end_tick is not None and w.next_frame >= w.end_tick - w.first_tick:
                self._seal()
        except AirSitlError as err:
            self._abandon(err)

    def _seal(self) -> None:
        from air_sitl.sinks import FlightResult

        w = self._window
        self._window = None
        if w is None:
            return
        last = self._last_sample
        t = last.state.sim_time_ns if last is not None else 0
        completed = bool(last.autopilot.mission_completed) if last is not None else False
        w.writer.close(FlightResult(mission_completed=completed, sim_time_ns=t, wall_time_s=0.0))
        summary = {
            "capture_distance_m": round(w.distance_m, 2),
            "capture_frames": w.next_frame,
            "capture_start_s": w.start_ns / 1e9,
            "mission_completed": completed,
            "sim_time_s": t / 1e9,
        }
        w.writer.finish(summary)
        self.archives.append(w.folder)
        print(f"air-sitl serve: recorded {w.next_frame} frames into {w.folder}", flush=True)

    def _abandon(self, err: Exception) -> None:
        w = self._window
        self._window = None
        self._failed = True  # no new archive before this capture window ends
        print(f"air-sitl serve: warning: recording stopped: {err}", file=sys.stderr, flush=True)
        if w is not None:
            with contextlib.suppress(Exception):
                w.writer.close(FlightResult(mission_completed=False, sim_time_ns=0, wall_time_s=0))

    def close(self, result: FlightResult) -> None:
        """The flight ended: seal the window in progress with what arrived."""
        from air_sitl.errors import AirSitlError

        try:
            self._seal()
        except AirSitlError as err:
            self._abandon(err)
