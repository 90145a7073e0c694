"""The camera in a process of its own (serve's view images): the same frames as the camera in
the flight's process, in order; the view's rate and its one image at a time."""

from __future__ import annotations

import io

from georef_helpers import HOME

from air_sitl.camera.model import CameraModel
from air_sitl.camera.options import open_chosen_renderer
from air_sitl.camera.process import ProcessCamera
from air_sitl.camera.render import render_camera_frame
from air_sitl.maps.choose import open_chosen_map
from air_sitl.options import MapChoice
from air_sitl.serving import ViewFrames

from .test_bridge import _samples

CAMERA = CameraModel(width_px=320, height_px=240)
CHOICE = MapChoice(spec="forest", seed=2)


def test_frames_equal_the_flight_process_camera_and_the_view_rate_holds() -> None:
    samples = _samples(30)  # 50 Hz ticks: 0.6 s of simulation
    camera = ProcessCamera(CHOICE, HOME, "", CAMERA, seed=9)
    got = []
    for i, s in enumerate(samples[:4]):
        camera.submit(s, i)
    got.extend(camera.flush())
    renderer = open_chosen_renderer(CHOICE, open_chosen_map(CHOICE, HOME, ""), CAMERA, 9)
    sync = [render_camera_frame(renderer, s, i) for i, s in enumerate(samples[:4])]
    assert [f.index for f in got] == [0, 1, 2, 3]
    assert [f.jpeg for f in got] == [f.jpeg for f in sync]
    assert [f.sim_time_ns for f in got] == [s.state.sim_time_ns for s in samples[:4]]

    # The view's images at 10 Hz of simulation: every 5th tick, each waited for here.
    said = io.StringIO()
    view = ViewFrames(camera, image_hz=10.0, out=said)
    frames = []
    for i, s in enumerate(samples):
        view.submit(s, i)
        frames.extend(view.flush())
    assert [f.index for f in frames] == [0, 5, 10, 15, 20, 25]
    assert view.skipped == 0
    # Not waited for: the next due image finds the camera busy and is skipped, counted.
    view = ViewFrames(camera, image_hz=50.0, out=said)
    view.submit(samples[0], 0)
    view.submit(samples[1], 1)
    assert view.skipped == 1
    assert [f.index for f in view.flush()] == [0]
    view.close()
    assert "foxglove: 1 camera images skipped" in said.getvalue()
    assert not camera.failed
