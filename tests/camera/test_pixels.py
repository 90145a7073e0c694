"""Pixel values users rely on: the sensor noise (its sigma, one field per seed and frame) and
the fill colour where rays miss the ground; also across the strips a frame is rendered in."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from georef_helpers import HOME, utm_grid
from vehicle_states import above

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import FILL_BGR, Renderer, pose_state
from air_sitl.maps.array import ArrayMap
from air_sitl.state import VehicleState

GREY = 128


@pytest.fixture(scope="module")
def flat_map() -> ArrayMap:
    """A uniform grey 4 km x 4 km map (1 m pixels) around home, on home's ground."""
    crs, transform, size = utm_grid(HOME, 1.0, 2000.0)
    image = np.full((size, size, 3), GREY, dtype=np.uint8)
    return ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)


def _pose(alt_agl_m: float, roll_deg: float = 0.0, pitch_deg: float = 0.0) -> VehicleState:
    return above(
        HOME,
        alt_agl_m,
        roll_rad=math.radians(roll_deg),
        pitch_rad=math.radians(pitch_deg),
        yaw_rad=0.3,
    )


def test_noise_has_the_camera_sigma_around_the_true_pixel(flat_map: ArrayMap) -> None:
    sigma = 1.8
    renderer = Renderer(flat_map, CameraModel(noise_sigma=sigma), seed=3)
    clean = renderer.render(_pose(300.0))
    assert (clean == GREY).all()
    noisy = renderer.render(_pose(300.0), noise_index=0).astype(np.float64)
    # Noise is rounded to whole grey levels: its variance is sigma^2 + 1/12.
    expected = math.sqrt(sigma**2 + 1.0 / 12.0)
    for channel in range(3):
        values = noisy[:, :, channel]
        assert abs(values.mean() - GREY) < 0.02
        assert values.std() == pytest.approx(expected, rel=0.03)


def test_noise_is_one_field_per_seed_and_frame_index(flat_map: ArrayMap) -> None:
    camera = CameraModel(noise_sigma=4.0)
    state = _pose(300.0)
    a = Renderer(flat_map, camera, seed=1)
    b = Renderer(flat_map, camera, seed=1)
    frame7 = a.render(state, noise_index=7)
    assert np.array_equal(frame7, b.render(state, noise_index=7))
    # The pipeline's fused noise is the same as adding it to the clean frame afterwards.
    assert np.array_equal(frame7, a.add_noise(a.render(state), 7))
    field7 = frame7.astype(np.float64) - GREY
    for other in (a.render(state, noise_index=8), Renderer(flat_map, camera, seed=2).render(
        state, noise_index=7
    )):  # fmt: skip
        field = other.astype(np.float64) - GREY
        corr = float((field7 * field).mean() / (field7.std() * field.std()))
        assert abs(corr) < 0.02, corr


def test_rays_that_miss_the_ground_get_the_fill_colour(flat_map: ArrayMap) -> None:
    camera = CameraModel(noise_sigma=0.0)
    renderer = Renderer(flat_map, camera)
    state = _pose(300.0, roll_deg=70.0)  # the horizon crosses the image
    img = renderer.render(state)
    # Each pixel's ray in NED; down component <= 0 never meets the ground.
    u, v = np.meshgrid(np.arange(camera.width_px), np.arange(camera.height_px))
    pix = np.stack([u, v, np.ones_like(u)], axis=-1).astype(np.float64)
    rays = (
        pix @ np.linalg.inv(camera.intrinsics()).T @ camera.r_cam_to_ned(state.q_body_to_ned_wxyz).T
    )
    down = rays[:, :, 2]
    sky = down <= 0.0
    horizontal_m = 300.0 * np.hypot(rays[:, :, 0], rays[:, :, 1]) / np.where(sky, 1.0, down)
    near_ground = ~sky & (horizontal_m < 1500.0)  # well inside the 4 km map
    assert 0.1 < sky.mean() < 0.9 and near_ground.mean() > 0.1
    assert (img[sky] == FILL_BGR).all()
    assert (img[near_ground] == GREY).all()


def test_a_camera_below_the_ground_sees_only_the_fill_colour(flat_map: ArrayMap) -> None:
    renderer = Renderer(flat_map, CameraModel(noise_sigma=0.0))
    state = pose_state(
        HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m - 5.0, alt_agl_m=-5.0, pitch_rad=0.1
    )
    assert renderer.map_xy_px(state) is None
    assert (renderer.render(state) == FILL_BGR).all()


@pytest.mark.parametrize("height_px", [480, 301, 16])
def test_strips_join_into_one_warp_of_the_whole_frame(height_px: int) -> None:
    """The frame, rendered in horizontal strips, equals one warp of the whole map image."""
    crs, transform, size = utm_grid(HOME, 1.0, 600.0)
    rng = np.random.default_rng(5)
    texture = cv2.GaussianBlur(rng.normal(128.0, 60.0, (size, size)), (0, 0), 2.0)
    image = np.repeat(np.clip(texture, 0, 255).astype(np.uint8)[:, :, None], 3, axis=2)
    m = ArrayMap(image, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    camera = CameraModel(noise_sigma=0.0, height_px=height_px)
    state = above(HOME, 200.0, roll_rad=0.2, pitch_rad=-0.1, yaw_rad=0.4)
    renderer = Renderer(m, camera)
    g = renderer.geometry(state)
    assert g.level == 0  # 0.34 m image pixels over a 1 m map
    got = renderer.render(state, g)
    want = cv2.warpPerspective(
        image,
        g.h_img_to_map0,
        (camera.width_px, camera.height_px),
        flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
    )
    diff = np.abs(got.astype(np.int16) - want)
    assert diff.max() <= 1  # fixed-point rounding of the per-strip coordinates
    assert (diff > 0).mean() < 0.01
