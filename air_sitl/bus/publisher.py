"""The zenoh publisher sink: frames, IMU, GNSS, clock, mission status and (opt-in) truth.

Runs on the simulation thread. Every put is drop-on-congestion: a slow subscriber loses
samples itself and never holds the simulation. Only in lockstep are frames published with
blocking congestion control (the simulation waits for the estimator anyway).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from air_sitl.bus import codec
from air_sitl.bus.keys import DEFAULT_VEHICLE, KeySpace
from air_sitl.bus.session import Bus, Publisher, QueryAnswer, QueryRequest
from air_sitl.clock import CAMERA_RATE_HZ, NS_PER_S
from air_sitl.errors import BusError
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import AutopilotStatus, CameraFrame, GeoPoint, SimSample


@dataclass(frozen=True, slots=True, kw_only=True)
class PublishOptions:
    """What to publish, and how often."""

    keys: KeySpace = KeySpace(DEFAULT_VEHICLE)  # noqa: RUF009 (frozen, so shared safely)
    publish_truth: bool = False
    imu_rate_hz: float = 200.0  # physics rate by default; decimated to a divisor of it
    home: GeoPoint | None = None  # sent in mission/status so clients can use ENU
    camera_info: codec.CameraInfo | None = None
    block_frames: bool = False  # lockstep: never drop a frame


class FrameLedger:
    """Frames published so far: index -> (sim time, wall time, capture index); shared with the
    estimate log.

    Written on the simulation thread, read on zenoh threads: guarded by a lock.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._wall_s: dict[int, float] = {}
        self._time_ns: dict[int, int] = {}
        self._index_by_time: dict[int, int] = {}
        # Frames whose capture index differs from their index (None: outside the window).
        self._capture: dict[int, int | None] = {}
        self.last_index = -1
        self.now_ns: int | None = None  # the flight's simulation time, published so far
        self.first_publish_wall_s: float | None = None  # monotonic time of the first frame
        self.count = 0

    def expose(self, index: int, sim_time_ns: int, capture_index: int | None) -> None:
        """Frame ``index`` is taken at ``sim_time_ns`` (``capture_index``: its index in the
        capture window, None when it is taken outside it). Known from the exposure on: an
        estimate may answer the truth of the exposure before the frame is published."""
        with self._lock:
            self._time_ns[index] = sim_time_ns
            self._index_by_time[sim_time_ns] = index
            if self.now_ns is None or sim_time_ns > self.now_ns:
                self.now_ns = sim_time_ns
            if capture_index != index:
                self._capture[index] = capture_index

    def record(self, index: int, sim_time_ns: int, capture_index: int | None) -> None:
        """Frame ``index`` was just published (see :meth:`expose` for the arguments)."""
        self.expose(index, sim_time_ns, capture_index)
        now = time.monotonic()
        with self._lock:
            self._wall_s[index] = now
            if self.first_publish_wall_s is None:
                self.first_publish_wall_s = now
            self.last_index = max(self.last_index, index)
            self.count += 1

    def capture_index(self, index: int) -> int | None:
        """The capture-window index of frame ``index`` (what the archive calls it); None for a
        frame taken outside the window (a camera kept on for an aid)."""
        with self._lock:
            return self._capture.get(index, index)

    def exposed(self, index: int) -> bool:
        """True once frame ``index`` was taken (its estimate may come before it is published)."""
        with self._lock:
            return index in self._time_ns

    def published(self, index: int) -> bool:
        """True once frame ``index`` went out."""
        with self._lock:
            return index in self._wall_s

    def lookup(
        self, frame: int | None, sim_time_ns: int | None
    ) -> tuple[int | None, int | None, float | None, int]:
        """(frame, sim time, publish wall time, last published index) for an estimate."""
        with self._lock:
            if frame is None and sim_time_ns is not None:
                frame = self._index_by_time.get(sim_time_ns)
            if frame is not None and sim_time_ns is None:
                sim_time_ns = self._time_ns.get(frame)
            wall = None if frame is None else self._wall_s.get(frame)
            return frame, sim_time_ns, wall, self.last_index


class BusPublisher(NullSink):
    """A :class:`~air_sitl.sinks.Sink` that puts the simulation on the bus."""

    def __init__(
        self, bus: Bus, options: PublishOptions, ledger: FrameLedger | None = None
    ) -> None:
        self.bus = bus
        self.options = options
        self.ledger = ledger or FrameLedger()
        k = options.keys
        js = codec.JSON_ENCODING
        self._imu = bus.publisher(k.imu, encoding=js)
        self._gps = bus.publisher(k.gps, encoding=js)
        self._clock = bus.publisher(k.clock, encoding=js)
        self._status = bus.publisher(k.mission_status, encoding=js)
        self._truth = bus.publisher(k.truth, encoding=js) if options.publish_truth else None
        self._image = bus.publisher(
            k.image, encoding=codec.JPEG_ENCODING, block=options.block_frames
        )
        self._info_pub = bus.publisher(k.info, encoding=js)
        self._info: bytes | None = None
        if options.camera_info is not None:
            self._info = codec.encode_camera_info(options.camera_info)
            self._info_pub.put(self._info)
        bus.queryable(k.info, self._answer_info)
        # Latest value of each small topic, answered to queries (late joiners start from it).
        self._latest: dict[str, bytes] = {}
        self._latest_lock = threading.Lock()
        latest_keys = [k.imu, k.gps, k.clock, k.mission_status]
        if options.publish_truth:
            latest_keys.append(k.truth)
        for key in latest_keys:
            bus.queryable(key, self._answer_latest)
        self._imu_every = max(1, round(200.0 / max(options.imu_rate_hz, 1e-9)))
        self._step = 0
        self._last_status: tuple[object, ...] | None = None
        self._last_status_ns = -NS_PER_S
        self.frames_published = 0
        self.frames_reoffered = 0
        # Lockstep: called once before the first IMU/GNSS sample goes out (after the first
        # status, which the estimator asks for before it subscribes to the frames).
        self.gate: Callable[[], None] | None = None

    @property
    def image_matched(self) -> bool:
        """True when a subscriber listens to ``camera/image``."""
        return self._image.matched

    def _answer_info(self, request: QueryRequest) -> QueryAnswer:
        info = self._info
        if info is None:
            msg = f"{self.options.keys.info}: this simulator has no camera"
            raise BusError(msg)
        return QueryAnswer(info, encoding=codec.JSON_ENCODING)

    def _answer_latest(self, request: QueryRequest) -> QueryAnswer:
        with self._latest_lock:
            payload = self._latest.get(request.key)
        if payload is None:
            msg = f"{request.key}: nothing published yet"
            raise BusError(msg)
        return QueryAnswer(payload, encoding=codec.JSON_ENCODING)

    def _put(self, publisher: Publisher, key: str, payload: bytes) -> None:
        publisher.put(payload)
        with self._latest_lock:
            self._latest[key] = payload

    def on_sample(self, sample: SimSample) -> None:
        """Status on change, then clock and IMU every step (IMU decimated), GNSS when fresh,
        truth."""
        k = self.options.keys
        t = sample.state.sim_time_ns
        self.ledger.now_ns = t  # estimates of a later time are from outside the flight
        status = sample.autopilot
        key = _status_key(status)
        if key != self._last_status or t - self._last_status_ns >= NS_PER_S:
            self._put(
                self._status, k.mission_status, codec.encode_status(t, status, self.options.home)
            )
            self._last_status = key
            self._last_status_ns = t
        if self.gate is not None:
            gate, self.gate = self.gate, None
            gate()
        self._put(self._clock, k.clock, codec.encode_clock(t))
        if self._step % self._imu_every == 0:
            self._put(self._imu, k.imu, codec.encode_imu(sample.imu))
        self._step += 1
        if sample.gps is not None:
            self._put(self._gps, k.gps, codec.encode_gps(sample.gps))
        tick = sample.camera
        if tick is not None:
            self.ledger.expose(tick.index, t, tick.capture_index)
        if self._truth is not None:
            frame = None if tick is None else tick.index
            self._put(self._truth, k.truth, codec.encode_truth(sample.state, frame))

    def on_frame(self, frame: CameraFrame) -> None:
        """Publish the frame unless the lockstep source already did."""
        if not self.ledger.published(frame.index):
            self.publish_frame(frame)

    def publish_frame(self, frame: CameraFrame) -> None:
        """JPEG payload + attachment (frame index, simulation time, size)."""
        if self._info is None:
            # No camera description was given: describe the frames as the SPEC default camera.
            info = codec.CameraInfo(
                width_px=frame.width_px,
                height_px=frame.height_px,
                hfov_deg=57.0,
                rate_hz=float(CAMERA_RATE_HZ),
                q_cam_to_body_wxyz=(0.7071067811865476, 0.0, 0.0, 0.7071067811865476),
            )
            self._info = codec.encode_camera_info(info)
            self._info_pub.put(self._info)
        # Recorded before the put: an estimate may come back before put() returns.
        tick = frame.sample.camera
        capture = frame.index if tick is None else tick.capture_index
        self.ledger.record(frame.index, frame.sim_time_ns, capture)
        self._image.put(frame.jpeg, _frame_meta(frame))
        self.frames_published += 1

    def reoffer_frame(self, frame: CameraFrame) -> None:
        """Put a published frame again, as it was (lockstep: its estimator may have lost it, or
        its answer, while the connection was down). Not counted as a new frame."""
        self.frames_reoffered += 1
        self._image.put(frame.jpeg, _frame_meta(frame))

    def close(self, result: FlightResult) -> None:
        """Nothing buffered: puts went out as they came."""


def _frame_meta(frame: CameraFrame) -> bytes:
    """The attachment of a frame on ``camera/image``."""
    meta = codec.FrameMeta(
        frame=frame.index,
        sim_time_ns=frame.sim_time_ns,
        width_px=frame.width_px,
        height_px=frame.height_px,
    )
    return codec.encode_frame_meta(meta)


def _status_key(status: AutopilotStatus) -> tuple[object, ...]:
    return (
        status.mode,
        status.armed,
        status.current_seq,
        status.capturing,
        status.mission_completed,
    )
