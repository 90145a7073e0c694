"""No moire at 3000 m: the pyramid level follows the ground sample distance."""

from __future__ import annotations

import functools
import math

import cv2
import numpy as np
import numpy.typing as npt
import pytest
from georef_helpers import HOME, utm_grid
from vehicle_states import above

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.maps.array import ArrayMap

ALT_M = 3000.0
GSD_M = 2.0


@functools.cache
def _grating() -> npt.NDArray[np.uint8]:
    """A sinusoidal grating of period 2.5 map px (5 m): far above the image Nyquist at 3000 m
    (made once: each map below copies it)."""
    _crs, _transform, size = utm_grid(HOME, GSD_M, 2200.0)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    a = math.radians(30.0)
    phase = (xx * math.cos(a) + yy * math.sin(a)) * (2 * math.pi / 2.5)
    gray = np.clip(128 + 100 * np.sin(phase), 0, 255).astype(np.uint8)
    bgr = np.dstack([gray] * 3)
    bgr.flags.writeable = False
    return bgr


@functools.cache
def _texture() -> npt.NDArray[np.uint8]:
    """Broadband random texture (detail at every scale down to the map pixel), made once."""
    _crs, _transform, size = utm_grid(HOME, GSD_M, 2200.0)
    rng = np.random.default_rng(3)
    noise = rng.normal(0, 1, (size, size)).astype(np.float32)
    tex = sum(cv2.GaussianBlur(noise, (0, 0), s) * s for s in (0.7, 2.0, 6.0))
    tex = 128 + 60 * tex / tex.std()
    gray = np.clip(tex, 0, 255).astype(np.uint8)
    bgr = np.dstack([gray] * 3)
    bgr.flags.writeable = False
    return bgr


def _map(bgr: npt.NDArray[np.uint8], levels: int | None) -> ArrayMap:
    """A map of its own (ArrayMap copies the pixels) over ``bgr``; ``levels=1``: a map without
    a pyramid, the naive renderer's."""
    crs, transform, _size = utm_grid(HOME, GSD_M, 2200.0)
    m = ArrayMap(bgr, crs=crs, transform=transform, ground_elevation_m=HOME.alt_amsl_m)
    if levels is not None:
        m.num_levels = levels
    return m


def _grating_map(levels: int | None = None) -> ArrayMap:
    return _map(_grating(), levels)


def _texture_map(levels: int | None = None) -> ArrayMap:
    return _map(_texture(), levels)


def _state(roll_deg: float = 0.0):  # type: ignore[no-untyped-def]
    return above(HOME, ALT_M, roll_rad=math.radians(roll_deg), yaw_rad=0.4)


@pytest.mark.parametrize("roll_deg", [0.0, 20.0])
def test_fine_grating_renders_flat_not_moire(roll_deg: float) -> None:
    camera = CameraModel(noise_sigma=0.0)
    good = Renderer(_grating_map(), camera).render(_state(roll_deg))[:, :, 0].astype(np.float64)
    naive = (
        Renderer(_grating_map(levels=1), camera)
        .render(_state(roll_deg))[:, :, 0]
        .astype(np.float64)
    )
    # The true image of a 5 m grating seen with 5.1 m pixels is its mean grey.
    # The far side of a banked frame runs off this small map: keep pixels well inside it.
    on_map = cv2.erode((good > 0).astype(np.uint8), np.ones((7, 7), np.uint8)) > 0
    good, naive = good[on_map], naive[on_map]
    assert abs(good.mean() - 128) < 3
    assert good.std() < 3.0, f"moire left: std {good.std():.2f}"
    assert naive.std() > 20.0, "the test pattern must alias without a pyramid"


def test_matches_supersampled_reference_at_3000m() -> None:
    camera = CameraModel(noise_sigma=0.0)
    big = CameraModel(width_px=4 * 640, height_px=4 * 480, noise_sigma=0.0)
    for roll in (0.0, 20.0):
        state = _state(roll)
        # Reference: 16 samples per pixel from the full-resolution map, box-averaged.
        ref_big = Renderer(_texture_map(levels=1), big).render(state)
        ref = cv2.resize(ref_big, (640, 480), interpolation=cv2.INTER_AREA)[:, :, 0].astype(
            np.float64
        )
        got = Renderer(_texture_map(), camera).render(state)[:, :, 0].astype(np.float64)
        naive = Renderer(_texture_map(levels=1), camera).render(state)[:, :, 0].astype(np.float64)
        err = np.abs(got - ref).mean()
        err_naive = np.abs(naive - ref).mean()
        print(f"roll {roll}: mean abs error {err:.2f} (naive {err_naive:.2f})")
        assert err < 6.0, f"roll {roll}: mean abs error {err:.2f} vs supersampled reference"
        assert err < err_naive, (
            f"roll {roll}: pyramid {err:.2f} not better than naive {err_naive:.2f}"
        )
