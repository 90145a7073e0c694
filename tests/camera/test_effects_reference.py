"""Frames with every camera effect stay within a stated tolerance of the frames the renderer
gave before issue 34 made the effects fast (``data/effects_*.png``: rendered by the code of
commit 397ca1b, 160 x 120, all six effects, no sensor noise): a roll at 45 deg/s at 200 m
(blur along the roll, rolling-shutter shear) and a straight line at 300 m.

Tolerance: the largest difference of a pixel's channel 20 grey levels, their mean 2.0 (the
blur now filters the sharp frame along each tile's path instead of averaging up to 16 frames
sampled from the map: a second bilinear resampling softens a blur shorter than two pixels).

And within 2 grey levels (mean 0.01) of the frames of commit f8f6f05 (``*_f8f6f05.png``),
before the blur, the light and the maps were compiled and the remap was made in strips: the
same sums, the blur's in float32 without OpenCV's fused multiply-adds (a sum landing on a
half rounds the other way); since the blur's sums are in 16-bit integers (its weights in
1/256), its pixels are within 1 grey level of the float32 sums, the frames' within 2
(against dbd08bc at 640 x 480: mean 0.01-0.04), so the tolerance holds."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest
from vehicle_states import above

from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.maps.open import open_map
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
ALL = ("blur", "rolling-shutter", "vignette", "exposure", "haze", "distortion")
DATA = Path(__file__).parent / "data"
MAX_DN = 20
MEAN_DN = 2.0
NOW_MAX_DN = 2  # against f8f6f05's frames
NOW_MEAN_DN = 0.01


@pytest.mark.parametrize(
    ("name", "alt_m", "roll_deg", "rate_deg_s"),
    [("roll200", 200.0, 20.0, 45.0), ("line300", 300.0, 3.0, 4.0)],
)
def test_effect_frames_stay_close_to_the_former_renderer(
    name: str, alt_m: float, roll_deg: float, rate_deg_s: float
) -> None:
    cam = CameraModel(
        width_px=160, height_px=120, noise_sigma=0.0, effects=CameraEffects(enabled=ALL)
    )
    renderer = Renderer(open_map("urban", HOME, seed=0), cam, seed=0)
    state = above(HOME, alt_m, roll_rad=math.radians(roll_deg), pitch_rad=0.03, yaw_rad=0.4)
    state = replace(
        state,
        vel_ned_m_s=(17.0, 6.0, 0.5),
        rate_frd_rad_s=(math.radians(rate_deg_s), 0.02, 0.03),
    )
    got = renderer.render(state, noise_index=7).astype(np.int16)
    want = cv2.imread(str(DATA / f"effects_{name}.png")).astype(np.int16)
    diff = np.abs(got - want)
    assert int(diff.max()) <= MAX_DN, (name, int(diff.max()))
    assert float(diff.mean()) <= MEAN_DN, (name, float(diff.mean()))
    now = np.abs(got - cv2.imread(str(DATA / f"effects_{name}_f8f6f05.png")).astype(np.int16))
    assert int(now.max()) <= NOW_MAX_DN, (name, int(now.max()))
    assert float(now.mean()) <= NOW_MEAN_DN, (name, float(now.mean()))
