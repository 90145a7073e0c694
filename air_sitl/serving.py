"""A served vehicle: the flight of a FlightSetup behind MAVLink links, flown by ground stations.

The vehicle starts on the ground at home, disarmed; clients (QGroundControl, MAVSDK, MAVProxy,
pymavlink) connect, upload a mission, arm and start it. The MAVLink endpoint's threads post
their commands to the simulation thread through the flight's inbox. ``out`` records each
capture window as an archive (:class:`~air_sitl.recording.CaptureRecorder`). ``video`` streams
the camera as RTP/H.264 (:class:`~air_sitl.video.stream.VideoStream`, a sink with a renderer of
its own: the archives stay the same bytes), described and started/stopped by the camera
component's video protocol.
"""

from __future__ import annotations

import queue
import sys
import threading
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import IO

import numpy as np
import numpy.typing as npt

from air_sitl.builder import FlightSetup, build_flight, open_camera, open_setup_map
from air_sitl.bus.hookup import BusHookup
from air_sitl.camera.options import open_chosen_renderer
from air_sitl.camera.process import ProcessCamera
from air_sitl.clock import CAMERA_PERIOD_NS, NS_PER_S
from air_sitl.maps.choose import close_map
from air_sitl.mavlink.codec import ParseCounters
from air_sitl.mavlink.interfaces import SEVERITY_CRITICAL, SEVERITY_ERROR
from air_sitl.mavlink.links import LinkSpec
from air_sitl.mavlink.nav_aid import NavLink
from air_sitl.mavlink.streams import TelemetrySink
from air_sitl.mavlink.telemetry import CameraInfo
from air_sitl.mavlink.vehicle import EndpointOptions, Job, VehicleEndpoint
from air_sitl.recording import CaptureRecorder
from air_sitl.runner import Flight, InboxItem
from air_sitl.sinks import FrameSource, Sink
from air_sitl.state import CameraFrame, SimSample
from air_sitl.video.options import VideoOptions
from air_sitl.video.stream import VideoCamera, VideoStream


def camera_info(setup: FlightSetup) -> CameraInfo | None:
    """What the camera component reports: the flight's camera (its --camera-* options)."""
    cam = setup.camera
    if cam is None:
        return None
    return CameraInfo(width_px=cam.width_px, height_px=cam.height_px, hfov_deg=cam.hfov_deg)


def open_video(setup: FlightSetup, options: VideoOptions) -> VideoStream:
    """The video stream of ``setup``'s camera, rendered by a renderer of its own (same map,
    camera and seed as the archive's; frames noised by their camera tick)."""
    cam = setup.camera
    assert cam is not None, "open_video: the setup flies without a camera"
    source = open_setup_map(setup)
    renderer = open_chosen_renderer(setup.map, source, cam, setup.options.seed)

    def render(sample: SimSample) -> npt.NDArray[np.uint8]:
        state = sample.state
        geometry = renderer.geometry(state, warn=False)
        return renderer.render(state, geometry, noise_index=state.sim_time_ns // CAMERA_PERIOD_NS)

    return VideoStream(
        options,
        VideoCamera(width_px=cam.width_px, height_px=cam.height_px, hfov_deg=cam.hfov_deg),
        render,
        on_close=lambda: close_map(renderer.map),
    )


def open_process_camera(setup: FlightSetup) -> ProcessCamera:
    """``setup``'s camera rendering in a process of its own (its map opened there)."""
    assert setup.camera is not None, "open_process_camera: the setup flies without a camera"
    return ProcessCamera(setup.map, setup.home, setup.name, setup.camera, setup.options.seed)


class ViewFrames:
    """The camera when only the live view takes its frames (a FrameSource), rendered in a
    process of its own (:class:`~air_sitl.camera.process.ProcessCamera`: its Python never holds
    the lock the paced simulation needs): a tick is rendered only when the view's next image is
    due (``image_hz`` a second of simulation, the view's own rule), not at every 50 Hz tick,
    and only when the previous one is back. A due image the camera is too busy for is skipped
    and counted (said at exit): the view never makes the served simulation wait for it."""

    def __init__(self, camera: ProcessCamera, image_hz: float, out: IO[str] = sys.stderr) -> None:
        self.camera = camera
        self._period_ns = int(NS_PER_S / image_hz)
        self._next_ns = 0
        self.skipped = 0
        self._out = out

    def submit(self, sample: SimSample, index: int) -> None:
        """Render the tick if the view's image is due and the camera free, else nothing."""
        t = sample.state.sim_time_ns
        if t < self._next_ns:
            return
        self._next_ns = t + self._period_ns
        if self.camera.in_flight:
            self.skipped += 1
            return
        self.camera.submit(sample, index)

    def ready(self) -> list[CameraFrame]:
        """The frames rendered so far."""
        return self.camera.ready()

    def flush(self) -> list[CameraFrame]:
        """The remaining frames."""
        return self.camera.flush()

    def close(self) -> None:
        """Stop the camera's process; say how many images were skipped."""
        self.camera.close()
        if self.skipped:
            print(
                f"foxglove: {self.skipped} camera images skipped (the camera was behind the "
                "flight)",
                file=self._out,
                flush=True,
            )
        if self.camera.failed:
            print("foxglove: the camera's process stopped (no more images)", file=self._out)


class CrashResponse:
    """After a crash (the flight's own ground-contact judgement, ``FlightStats.crashed``) the
    served vehicle disarms, motors off, and says once where and why (STATUSTEXT CRITICAL);
    the simulation goes on, so clients see it disarmed on the ground and may arm again."""

    def __init__(self, flight: Flight, telemetry: TelemetrySink) -> None:
        self._flight = flight
        self._telemetry = telemetry
        self.reported = False

    def then(self, stop: Callable[[], bool]) -> Callable[[SimSample], bool]:
        """A ``Flight.run`` stop test that first responds to a new crash."""

        def check(_sample: SimSample) -> bool:
            crash = self._flight.stats.crashed
            if crash is not None and not self.reported:
                self.reported = True
                self._flight.autopilot.crashed()
                self._telemetry.announce(
                    SEVERITY_CRITICAL,
                    f"Crashed at {crash['sim_time_s']:.1f} s: {crash['reason']}; disarmed",
                )
            return stop()

        return check


def serve_vehicle(
    setup: FlightSetup,
    links: Sequence[LinkSpec],
    *,
    stop: threading.Event,
    max_sim_time_ns: int,
    bus: BusHookup,
    out: Path | None = None,
    signing_key: bytes | None = None,
    quiet: bool = False,
    system_id: int = 1,
    video: VideoOptions | None = None,
    home_note: str = "",
    view: Sink | None = None,
    view_image_hz: float = 0.0,
    on_attached: Callable[[BusHookup, VehicleEndpoint], None] | None = None,
) -> ParseCounters:
    """Fly ``setup`` for MAVLink clients until ``stop`` is set; what the links received.

    ``system_id``: MAV_SYS_ID (instance N of several is N+1). ``video``: stream the camera
    (ignored without a camera); what it sent and dropped is printed when it stops.
    ``home_note``: where the home came from, said in the ready line (a default home).
    ``view``: one more sink (the Foxglove live view; ``view_image_hz`` > 0: it wants camera
    frames at that rate of simulation time, rendered when the vehicle has a camera, only at
    that rate when nothing else takes them); ``on_attached(bus, endpoint)`` once both are up
    (the view's estimates and STATUSTEXT)."""
    inbox: queue.SimpleQueue[InboxItem] = queue.SimpleQueue()

    def post(job: Job) -> None:
        def on_flight(flight: Flight) -> None:
            job(flight.autopilot)

        inbox.put(on_flight)

    home = setup.home
    stream = open_video(setup, video) if video is not None and setup.camera is not None else None
    endpoint = VehicleEndpoint(
        list(links),
        home=home,
        mission=setup.mission,
        post=post,
        options=EndpointOptions(
            system_id=system_id,
            signing_key=signing_key,
            camera=camera_info(setup),
            terrain=setup.map.dem is not None,
            video=stream,
        ),
    )
    started = False  # the vehicle was ready: only then has the video a summary to give
    try:
        addresses = endpoint.open()
        # The onboard estimate's telemetry (and, with --nav-aid mavlink, its aids).
        nav_link = NavLink(endpoint, aid=setup.options.nav_aid == "mavlink")
        sinks: list[Sink] = [endpoint.sink, nav_link]
        if stream is not None:
            sinks.append(stream)
        camera: FrameSource | None = None
        recorder = None
        if out is not None or bus.needs_camera:
            camera = open_camera(setup, open_setup_map(setup))
        elif view_image_hz > 0 and setup.camera is not None:
            camera = ViewFrames(open_process_camera(setup), view_image_hz)
        if out is not None:
            recorder = CaptureRecorder(out, setup)
            sinks.append(recorder)
        bus_sinks, camera = bus.attach(
            home=home,
            out=out,
            camera=setup.camera if camera is not None else None,
            seed=setup.options.seed,
            frame_source=camera,
        )
        sinks.extend(bus_sinks)
        if view is not None:
            sinks.append(view)
        if on_attached is not None:
            on_attached(bus, endpoint)
        flight = build_flight(setup, sinks=sinks, camera=camera, auto_start=False)
        if flight.nav is not None and setup.options.nav_aid not in (None, "mavlink"):
            flight.nav.aid_feed = bus.nav_aid_feed(str(setup.options.nav_aid))
        if flight.nav is not None:
            nav_link.attach(flight.nav, flight.autopilot.params)
        endpoint.attach(flight.autopilot, flight.autopilot.params)
        if recorder is not None:
            recorder.autopilot = flight.autopilot
            recorder.on_failure = lambda text: endpoint.text(SEVERITY_ERROR, text)
        endpoint.start()
        if not quiet:
            where = ", ".join(
                f"{spec} (local {host}:{port})"
                for spec, (host, port) in zip(links, addresses, strict=True)
            )
            shown = f"; video: {stream.options.url}" if stream is not None else ""
            print(
                f"air-sitl serve: vehicle ready at {home.lat_deg:.7f},{home.lon_deg:.7f},"
                f"{home.alt_amsl_m:.1f}{f' ({home_note})' if home_note else ''} "
                f"speed {setup.options.speed:g}; links: {where}{shown}",
                flush=True,
            )
        crash = CrashResponse(flight, endpoint.sink)
        started = True
        flight.run(stop=crash.then(stop.is_set), max_sim_time_ns=max_sim_time_ns, inbox=inbox)
    finally:
        endpoint.close()
        if stream is not None:
            stream.close()
            if not quiet and started:  # a link refused (port in use): its error alone
                print(video_summary(stream), flush=True)
    return endpoint.counters


def video_summary(stream: VideoStream) -> str:
    """The stream's line at exit: frames sent and dropped (the encoder was behind)."""
    c = stream.counters
    errors = f", {c.errors} failed" if c.errors else ""
    return (
        f"air-sitl serve: video: {c.frames_sent} frames sent to {stream.options.url} "
        f"({stream.datagrams_sent} RTP packets), {c.frames_dropped} dropped{errors}"
    )
