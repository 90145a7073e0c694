"""The camera over the bus: a remote FrameSource (``fly --camera remote``) and the bridge server.

Lockstep rendering is a zenoh query on ``air/<vehicle>/camera/render``: the payload is the
``truth`` message of the exposure (with ``frame``), the attachment names what to render with
(home, camera model fields, noise seed), and the reply is the JPEG with a frame attachment
carrying ``map_xy_px`` and ``nodata_fraction`` (the frame's share of map nodata, which the
flight's nodata warning and ``frames_with_nodata`` count as for the in-process camera). A
frame whose answer does not come is asked again until the timeout; nothing is ever skipped,
and the renderer being a pure function of (map, camera, state, index, seed), the images are
byte-identical to the in-process camera's.

The same server also runs free: it subscribes to ``truth`` and publishes ``camera/image`` for
every truth sample that carries a frame index (a simulator with ``--publish-truth`` and no
camera of its own).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import Bus, Message, QueryAnswer, QueryRequest
from air_sitl.errors import BusError
from air_sitl.state import CameraFrame, GeoPoint, SimSample, VehicleState


@dataclass(frozen=True, slots=True)
class RenderedFrame:
    """What a renderer returns for one pose."""

    jpeg: bytes
    map_xy_px: tuple[int, int]
    width_px: int
    height_px: int
    nodata_fraction: float = 0.0  # share of the image showing map nodata or off-map ground


RenderFn = Callable[[VehicleState, int], RenderedFrame]


@dataclass(frozen=True, slots=True, kw_only=True)
class RenderSettings:
    """What a render request asks for: home (places procedural maps), camera, noise seed."""

    home: GeoPoint
    camera: dict[str, Any]  # CameraModel fields
    seed: int

    def encode(self) -> bytes:
        """Query attachment JSON."""
        h = self.home
        return codec.dumps(
            {
                "home": {"lat_deg": h.lat_deg, "lon_deg": h.lon_deg, "alt_amsl_m": h.alt_amsl_m},
                "camera": self.camera,
                "seed": self.seed,
            }
        )

    @staticmethod
    def decode(attachment: bytes | None) -> RenderSettings:
        """Inverse of :meth:`encode`."""
        if attachment is None:
            msg = "camera/render: query without settings attachment"
            raise BusError(msg)
        m = codec.loads(attachment, "camera/render settings")
        with codec.fields_of("camera/render settings", "value"):
            home = codec.decode_geo(m["home"])
            return RenderSettings(home=home, camera=dict(m["camera"]), seed=int(m["seed"]))


RendererFactory = Callable[[RenderSettings], RenderFn]


class RemoteCamera:
    """A :class:`~air_sitl.sinks.FrameSource` whose frames a camera bridge renders.

    Up to ``max_in_flight`` queries run at once (the simulation keeps stepping meanwhile);
    frames come out strictly in index order.
    """

    def __init__(
        self,
        bus: Bus,
        keys: KeySpace,
        settings: RenderSettings,
        *,
        timeout_s: float = 10.0,
        max_in_flight: int = 8,
    ) -> None:
        self.bus = bus
        self.keys = keys
        self._settings = settings.encode()
        self.timeout_s = timeout_s
        self.max_in_flight = max(1, max_in_flight)
        self._cond = threading.Condition()
        self._order: deque[int] = deque()
        self._samples: dict[int, SimSample] = {}
        self._done: dict[int, CameraFrame | str] = {}
        self._closed = False
        self.retries = 0

    def submit(self, sample: SimSample, index: int) -> None:
        """Ask the bridge for frame ``index`` (waits while too many are in flight)."""
        with self._cond:
            deadline = time.monotonic() + self.timeout_s
            while len(self._order) - len(self._done) >= self.max_in_flight:
                left = deadline - time.monotonic()
                if left <= 0:
                    self._fail_slow()
                self._cond.wait(left)
            self._order.append(index)
            self._samples[index] = sample
        self._ask(index, sample, time.monotonic() + self.timeout_s)

    def _ask(self, index: int, sample: SimSample, deadline: float) -> None:
        if self._closed:
            return
        payload = codec.encode_truth(sample.state, index)

        def on_answer(message: Message | None, error: str | None) -> None:
            if message is not None:
                self._accept(index, message)
                return
            assert error is not None
            if error.startswith("no answer") and time.monotonic() < deadline and not self._closed:
                # No bridge yet (or it restarted): ask again shortly, never skip the frame.
                self.retries += 1
                timer = threading.Timer(0.05, self._ask, (index, sample, deadline))
                timer.daemon = True
                timer.start()
                return
            if error.startswith("no answer"):
                self._finish(index, self._silence(index))
            else:
                self._finish(index, f"camera bridge, frame {index}: {error}")

        left = max(0.1, deadline - time.monotonic())
        try:
            self.bus.query_async(
                self.keys.render, payload, on_answer, attachment=self._settings, timeout_s=left
            )
        except BusError as err:
            self._finish(index, str(err))

    def _accept(self, index: int, message: Message) -> None:
        try:
            meta = codec.decode_frame_meta(message.attachment)
        except BusError as err:
            self._finish(index, str(err))
            return
        if meta.frame != index:
            self._finish(index, f"camera bridge answered frame {meta.frame} for frame {index}")
            return
        with self._cond:
            sample = self._samples.get(index)
        if sample is None:
            return
        frame = CameraFrame(
            index=index,
            sim_time_ns=sample.state.sim_time_ns,
            jpeg=message.payload,
            width_px=meta.width_px,
            height_px=meta.height_px,
            sample=sample,
            map_xy_px=meta.map_xy_px or (-1, -1),
            nodata_fraction=meta.nodata_fraction or 0.0,
        )
        self._finish(index, frame)

    def _finish(self, index: int, result: CameraFrame | str) -> None:
        with self._cond:
            self._done[index] = result
            self._cond.notify_all()

    def _pop_ready(self) -> list[CameraFrame]:
        out: list[CameraFrame] = []
        while self._order and self._order[0] in self._done:
            index = self._order.popleft()
            result = self._done.pop(index)
            self._samples.pop(index, None)
            if isinstance(result, str):
                raise BusError(result)
            out.append(result)
        return out

    def ready(self) -> list[CameraFrame]:
        """Frames answered so far, in index order, without waiting."""
        with self._cond:
            return self._pop_ready()

    def flush(self) -> list[CameraFrame]:
        """Wait for every frame asked for (BusError if the bridge stops answering)."""
        out: list[CameraFrame] = []
        with self._cond:
            deadline = time.monotonic() + self.timeout_s + 1.0
            while True:
                out += self._pop_ready()
                if not self._order:
                    return out
                left = deadline - time.monotonic()
                if left <= 0:
                    self._fail_slow()
                self._cond.wait(left)

    def _silence(self, index: int) -> str:
        return (
            f"--camera remote: no frame {index} from a camera bridge on {self.keys.render} "
            f"within {self.timeout_s:g} s (is `air-sitl camera-bridge` running?)"
        )

    def _fail_slow(self) -> None:
        raise BusError(self._silence(self._order[0] if self._order else -1))

    def close(self) -> None:
        """Stop asking (late answers are ignored)."""
        with self._cond:
            self._closed = True
            self._order.clear()
            self._samples.clear()
            self._done.clear()


class CameraBridgeServer:
    """Serves renders on the bus: the queryable (lockstep) and the truth subscriber (free)."""

    def __init__(
        self,
        bus: Bus,
        keys: KeySpace,
        factory: RendererFactory,
        *,
        free_settings: Callable[[GeoPoint], RenderSettings] | None = None,
        on_published: Callable[[int, int, bytes], None] | None = None,
    ) -> None:
        self.bus = bus
        # Told (frame, sim time ns, JPEG) of each frame published from truth (camera-bridge
        # --ros2 publishes it as ROS 2 too).
        self.on_published = on_published
        self.keys = keys
        self._factory = factory
        self._free_settings = free_settings
        self._lock = threading.Lock()
        self._renderers: dict[bytes, RenderFn] = {}
        self._home: GeoPoint | None = None
        self.rendered = 0
        self.published = 0
        self.errors: list[str] = []
        bus.queryable(keys.render, self._on_query)
        if free_settings is not None:
            self._image = bus.publisher(keys.image, encoding=codec.JPEG_ENCODING)
            bus.subscribe(keys.mission_status, self._on_status)
            bus.subscribe(keys.truth, self._on_truth)

    def _renderer(self, settings: RenderSettings) -> RenderFn:
        key = settings.encode()
        with self._lock:
            fn = self._renderers.get(key)
            if fn is None:
                fn = self._factory(settings)
                self._renderers[key] = fn
            return fn

    def _on_query(self, request: QueryRequest) -> QueryAnswer:
        settings = RenderSettings.decode(request.attachment)
        m = codec.loads(request.payload, "camera/render")
        frame = m.get("frame")
        if not isinstance(frame, int):
            msg = "camera/render: the truth payload has no integer 'frame'"
            raise BusError(msg)
        state = codec.decode_state(m, "camera/render")
        try:
            out = self._renderer(settings)(state, frame)
        except BusError:
            raise
        except Exception as err:
            # A map or camera problem is the caller's to see, not a crash of the bridge.
            msg = f"camera/render frame {frame}: {type(err).__name__}: {err}"
            self.errors.append(msg)
            raise BusError(msg) from None
        meta = self._rendered(frame, state, out, render_reply=True)
        return QueryAnswer(out.jpeg, meta, codec.JPEG_ENCODING)

    def _rendered(
        self,
        frame: int,
        state: VehicleState,
        out: RenderedFrame,
        *,
        render_reply: bool = False,
    ) -> bytes:
        """Count a rendered frame and return its attachment (:class:`codec.FrameMeta`); a
        render reply adds ``map_xy_px`` and ``nodata_fraction`` (``camera/image`` has neither)."""
        self.rendered += 1
        meta = codec.FrameMeta(
            frame=frame,
            sim_time_ns=state.sim_time_ns,
            width_px=out.width_px,
            height_px=out.height_px,
            map_xy_px=out.map_xy_px if render_reply else None,
            nodata_fraction=out.nodata_fraction if render_reply else None,
        )
        return codec.encode_frame_meta(meta)

    def _on_status(self, message: Message) -> None:
        home = codec.loads(message.payload, message.key).get("home")
        if isinstance(home, dict) and self._home is None:
            self._home = codec.decode_geo(home)

    def _home_now(self) -> GeoPoint | None:
        """Home from the status seen so far, else asked for (callbacks race each other)."""
        if self._home is None:
            try:
                self._on_status(self.bus.query(self.keys.mission_status, timeout_s=1.0))
            except BusError:
                return None
        return self._home

    def _on_truth(self, message: Message) -> None:
        m = codec.loads(message.payload, message.key)
        frame = m.get("frame")
        if not isinstance(frame, int) or self._free_settings is None:
            return
        home = self._home_now()
        if home is None:
            return
        state = codec.decode_state(m)
        out = self._renderer(self._free_settings(home))(state, frame)
        self._image.put(out.jpeg, self._rendered(frame, state, out))
        self.published += 1
        if self.on_published is not None:
            self.on_published(frame, state.sim_time_ns, out.jpeg)
