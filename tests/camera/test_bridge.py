"""The camera bridge: ordered, deterministic, bounded, same frames as the synchronous path."""

from __future__ import annotations

import math

from georef_helpers import HOME

from air_sitl.camera.bridge import CameraBridge
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state, render_camera_frame
from air_sitl.frames import ned2geodetic
from air_sitl.maps.open import open_map
from air_sitl.state import SimSample, mission_sample


def _samples(n: int) -> list[SimSample]:
    out = []
    for i in range(n):
        lat, lon, _ = ned2geodetic(0.3 * i, 0.0, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
        state = pose_state(
            lat,
            lon,
            HOME.alt_amsl_m + 300.0,
            alt_agl_m=300.0,
            roll_rad=0.2 * math.sin(i / 5),
            sim_time_ns=20_000_000 * i,
        )
        out.append(mission_sample(state))
    return out


def test_threaded_frames_are_ordered_and_equal_to_sync() -> None:
    samples = _samples(24)
    renderer = Renderer(open_map("forest", HOME, seed=2), CameraModel(), seed=9)
    bridge = CameraBridge(renderer, workers=2, max_pending=4)
    got = []
    for i, s in enumerate(samples):
        bridge.submit(s, i)
        got.extend(bridge.ready())
        assert bridge.in_flight <= 4  # bounded memory
    got.extend(bridge.flush())
    bridge.close()
    assert [f.index for f in got] == list(range(24))
    sync = [render_camera_frame(renderer, s, i) for i, s in enumerate(samples)]
    assert [f.jpeg for f in got] == [f.jpeg for f in sync]
    assert all(f.sim_time_ns == s.state.sim_time_ns for f, s in zip(got, samples, strict=True))
    assert got[0].map_xy_px != got[-1].map_xy_px
    assert (got[0].width_px, got[0].height_px) == (640, 480)


def test_inline_bridge_without_workers() -> None:
    renderer = Renderer(open_map("urban", HOME), CameraModel(width_px=320, height_px=240))
    bridge = CameraBridge(renderer, workers=0)
    for i, s in enumerate(_samples(3)):
        bridge.submit(s, i)
    frames = bridge.ready()
    assert [f.index for f in frames] == [0, 1, 2]
    assert bridge.flush() == []
    bridge.close()
