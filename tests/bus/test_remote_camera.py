"""The camera over the bus: queries answered by the bridge server, byte-identical frames."""

from __future__ import annotations

import threading

import pytest

from air_sitl.bus.codec import decode_frame_meta
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import BusPublisher, PublishOptions
from air_sitl.bus.remote_camera import (
    CameraBridgeServer,
    RemoteCamera,
    RenderedFrame,
    RenderFn,
    RenderSettings,
)
from air_sitl.bus.session import Message
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, render_camera_frame
from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.errors import BusError
from air_sitl.maps.open import open_map
from air_sitl.state import GeoPoint, VehicleState

from .helpers import HOME, SAFETY_S, free_endpoint, make_sample, pair, wait_until

KEYS = KeySpace("rc")
CAMERA = CameraModel(width_px=200, height_px=150, hfov_deg=60.0, mount_rpy_deg=(2.0, -3.0, 0.0))


def factory(settings: RenderSettings) -> RenderFn:
    """What `air-sitl camera-bridge --map urban` builds for a render request."""
    c = settings.camera
    camera = CameraModel(
        width_px=c["width_px"],
        height_px=c["height_px"],
        hfov_deg=c["hfov_deg"],
        mount_rpy_deg=tuple(c["mount_rpy_deg"]),
        noise_sigma=c["noise_sigma"],
        jpeg_quality=c["jpeg_quality"],
    )
    renderer = Renderer(open_map("urban", settings.home), camera, seed=settings.seed)

    def render(state: VehicleState, index: int) -> RenderedFrame:
        jpeg, xy = renderer.frame_jpeg(state, index)
        return RenderedFrame(jpeg, xy, camera.width_px, camera.height_px)

    return render


def test_remote_frames_are_byte_identical_in_order_and_wait_for_a_late_bridge() -> None:
    sim, bridge = pair(free_endpoint())
    with sim, bridge:
        settings = RenderSettings(home=HOME, camera=CAMERA.settings(), seed=11)
        remote = RemoteCamera(sim, KEYS, settings, timeout_s=SAFETY_S, max_in_flight=4)
        samples = [
            make_sample(k * CAMERA_PERIOD_NS, east_m=0.3 * k, yaw_rad=1.0 + 0.01 * k)
            for k in range(12)
        ]
        remote.submit(samples[0], 0)  # nobody serves yet: asked again until the bridge is up
        # The bridge comes up once the first ask went unanswered (on a loaded machine the ask
        # could still be in flight when the bridge declares itself, and be answered).
        assert wait_until(lambda: remote.retries >= 1)
        server = CameraBridgeServer(bridge, KEYS, factory)
        frames = []
        for k in range(1, 12):
            remote.submit(samples[k], k)
            frames += remote.ready()
        frames += remote.flush()
        remote.close()
        local = Renderer(open_map("urban", HOME), CAMERA, seed=11)
        assert [f.index for f in frames] == list(range(12))
        for k, frame in enumerate(frames):
            expected = render_camera_frame(local, samples[k], k)
            assert frame.jpeg == expected.jpeg, f"frame {k} differs"
            assert frame.map_xy_px == expected.map_xy_px
            assert (frame.width_px, frame.height_px) == (200, 150)
            assert frame.sample is samples[k] and frame.sim_time_ns == samples[k].state.sim_time_ns
        assert server.rendered == 12 and remote.retries >= 1


def test_bridge_errors_and_silence_end_the_flight_with_one_line() -> None:
    sim, bridge = pair(free_endpoint())
    with sim, bridge:
        CameraBridgeServer(bridge, KEYS, factory)
        bad = RenderSettings(home=HOME, camera={"width_px": 3}, seed=0)
        remote = RemoteCamera(sim, KEYS, bad, timeout_s=SAFETY_S)
        remote.submit(make_sample(0), 0)
        with pytest.raises(BusError, match=r"camera bridge, frame 0: .*KeyError"):
            remote.flush()
        remote.close()
        silent = RemoteCamera(sim, KeySpace("nobody"), bad, timeout_s=0.5)
        silent.submit(make_sample(0), 0)
        with pytest.raises(BusError, match=r"--camera remote: no frame 0 .* within 0\.5 s"):
            silent.flush()
        silent.close()


def test_free_running_bridge_renders_truth_with_a_frame_index() -> None:
    sim, bridge = pair(free_endpoint())
    with sim, bridge:

        def free(home: GeoPoint) -> RenderSettings:
            return RenderSettings(home=home, camera=CAMERA.settings(), seed=5)

        server = CameraBridgeServer(bridge, KEYS, factory, free_settings=free)
        got: list[Message] = []
        lock = threading.Lock()

        def keep(m: Message) -> None:
            with lock:
                got.append(m)

        sim.subscribe(KEYS.image, keep)
        pub = BusPublisher(sim, PublishOptions(keys=KEYS, publish_truth=True, home=HOME))
        assert wait_until(lambda: pub._truth is not None and pub._truth.matched)
        assert wait_until(lambda: pub._status.matched)
        # 200 Hz physics, a camera exposure every 4th step (50 Hz): frames 0..9.
        samples = [
            make_sample(i * 5_000_000, east_m=0.075 * i, frame=i // 4 if i % 4 == 0 else None)
            for i in range(40)
        ]
        for s in samples:
            pub.on_sample(s)
        ok = wait_until(lambda: len(got) == 10)
        assert ok, (len(got), server.rendered, bridge.callback_errors)
        local = Renderer(open_map("urban", HOME), CAMERA, seed=5)
        for m in got:
            meta = decode_frame_meta(m.attachment)
            assert meta.sim_time_ns == samples[4 * meta.frame].state.sim_time_ns
            assert m.payload == render_camera_frame(local, samples[4 * meta.frame], meta.frame).jpeg
        assert sorted(decode_frame_meta(m.attachment).frame for m in got) == list(range(10))
        assert server.published == len(got)
