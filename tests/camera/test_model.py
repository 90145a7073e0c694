"""Camera model conventions: intrinsics, nose at the top, right wing to the right, mounting."""

from __future__ import annotations

import math

import numpy as np
import pytest

from air_sitl.camera.model import CameraModel
from air_sitl.errors import CameraError
from air_sitl.frames import euler2quat


def test_intrinsics_follow_width_and_fov() -> None:
    cam = CameraModel()
    assert cam.fx_px == pytest.approx(320.0 / math.tan(math.radians(28.5)))
    assert round(cam.fx_px, 1) == 589.4  # SPEC: "about 589.3"
    k = cam.intrinsics()
    assert k[0, 0] == k[1, 1] == cam.fx_px
    assert (k[0, 2], k[1, 2]) == (319.5, 239.5)


def test_nose_at_top_right_wing_right() -> None:
    cam = CameraModel()
    level_north = euler2quat(0.0, 0.0, 0.0)
    p = cam.project_ned(
        [(10.0, 0.0, 100.0), (0.0, 10.0, 100.0), (0.0, 0.0, 100.0)], (0, 0, 0), level_north
    )
    ahead, right, below = p
    assert below == pytest.approx((319.5, 239.5))
    assert ahead[1] < below[1] and ahead[0] == pytest.approx(319.5)  # north = nose = up
    assert right[0] > below[0] and right[1] == pytest.approx(239.5)  # east = right wing = right
    # Heading east: north is now to the left of the image.
    east = euler2quat(0.0, 0.0, math.pi / 2)
    q = cam.project_ned([(10.0, 0.0, 100.0)], (0, 0, 0), east)[0]
    assert q[0] < 319.5 and q[1] == pytest.approx(239.5)
    # Roll right 10 deg: the camera swings to look left, so the ground under the aircraft
    # appears toward the (lowered) right wing, right of the centre.
    rolled = euler2quat(math.radians(10.0), 0.0, 0.0)
    r = cam.project_ned([(0.0, 0.0, 100.0)], (0, 0, 0), rolled)[0]
    assert r[0] == pytest.approx(319.5 + cam.fx_px * math.tan(math.radians(10.0)))


def test_mounting_rotation_and_points_behind() -> None:
    cam = CameraModel(mount_rpy_deg=(0.0, 30.0, 0.0))
    r = cam.r_cam_to_body()
    assert np.allclose(r @ r.T, np.eye(3))
    # Tilted nose-up 30 deg, the optical axis points forward-down.
    axis = r @ np.array([0.0, 0.0, 1.0])
    assert axis[0] == pytest.approx(math.sin(math.radians(30.0)))
    p = CameraModel().project_ned([(0.0, 0.0, -5.0)], (0, 0, 0), euler2quat(0, 0, 0))
    assert np.isnan(p).all()


@pytest.mark.parametrize(
    "kwargs",
    [
        {"width_px": 0},
        {"hfov_deg": 0.0},
        {"noise_sigma": -1.0},
        {"jpeg_quality": 101},
        {"mount_rpy_deg": (0.0, float("nan"), 0.0)},
    ],
)
def test_bad_camera_values(kwargs: dict[str, object]) -> None:
    with pytest.raises(CameraError):
        CameraModel(**kwargs)  # type: ignore[arg-type]
