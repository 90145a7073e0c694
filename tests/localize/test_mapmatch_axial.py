"""``mapmatch-axial`` against ``mapmatch`` on frames whose contrast is reversed.

Frames rendered from the urban map (date 0) at 200 m and matched against the same map from a
prior 15 m off: as rendered both methods find them; reversed (255 - image, as a whole or in
every other cell of a 4 x 4 grid: regions brighter one year and darker the next) ``mapmatch``
refuses them and ``mapmatch-axial`` finds them where they are. Real map, real renderer, the
methods' own matchers and gates.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
import numpy.typing as npt
import pytest

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import ned2geodetic
from air_sitl.localize import METHODS
from air_sitl.localize.mapmatch import MapMatchLocalizer
from air_sitl.localize.mapmatch_axial import axial_correlation
from air_sitl.localize.mapmatch_core import MapMatcher, Rectified
from air_sitl.maps import open_map
from air_sitl.state import GeoPoint, Quat

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0)
HEIGHT_M = 200.0
POSES = ((310.0, -240.0, 0.4), (-520.0, 380.0, 2.1))  # east m, north m, heading rad
Gray = npt.NDArray[np.uint8]


def reversed_contrast(gray: Gray, how: str) -> Gray:
    if how == "global":
        return np.asarray(255 - gray, dtype=np.uint8)
    h, w = gray.shape
    yy, xx = np.mgrid[0:h, 0:w]
    cells = (yy * 4 // h + xx * 4 // w) % 2 == 0
    return np.where(cells, 255 - gray, gray).astype(np.uint8)


@pytest.fixture(scope="module")
def frames() -> list[tuple[Gray, Quat, float, float]]:
    """Grey frames of the urban map at date 0, with their attitude and true position."""
    renderer = Renderer(open_map("urban", HOME, seed=0, date=0), CameraModel(), seed=0)
    out = []
    for east, north, yaw in POSES:
        lat, lon, _ = ned2geodetic(north, east, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        state = pose_state(lat, lon, HOME.alt_amsl_m + HEIGHT_M, alt_agl_m=HEIGHT_M, yaw_rad=yaw)
        gray = cv2.cvtColor(renderer.render(state, noise_index=0), cv2.COLOR_BGR2GRAY)
        out.append((np.asarray(gray, dtype=np.uint8), state.q_body_to_ned_wxyz, east, north))
    return out


def matcher(method: str) -> MapMatcher:
    loc = METHODS[method]()
    assert isinstance(loc, MapMatchLocalizer)
    reference = open_map("urban", HOME, seed=0, date=0)
    return MapMatcher(reference, CameraModel(), HOME, **loc.matcher_options())


def error_m(m: MapMatcher, gray: Gray, q: Quat, east: float, north: float) -> float | None:
    """Horizontal error of an accepted match (None: refused)."""
    res = m.match(gray, q, HEIGHT_M, east + 12.0, north - 9.0, 25.0)
    assert res is not None
    return math.hypot(res.east_m - east, res.north_m - north) if res.accepted else None


def test_both_find_frames_as_rendered(frames: list[tuple[Gray, Quat, float, float]]) -> None:
    for method in ("mapmatch", "mapmatch-axial"):
        m = matcher(method)
        for gray, q, east, north in frames:
            err = error_m(m, gray, q, east, north)
            assert err is not None and err < 1.0, (method, err)


@pytest.mark.parametrize("how", ["global", "checker"])
def test_reversed_contrast_defeats_mapmatch_not_the_axial_one(
    frames: list[tuple[Gray, Quat, float, float]], how: str
) -> None:
    plain, axial = matcher("mapmatch"), matcher("mapmatch-axial")
    for gray, q, east, north in frames:
        flipped = reversed_contrast(gray, how)
        assert error_m(plain, flipped, q, east, north) is None  # refused
        err = error_m(axial, flipped, q, east, north)
        assert err is not None and err < 1.0, err


def test_axial_correlation_is_blind_to_the_sign_of_gradients() -> None:
    """The score map of an image and of its negative: the same (to float rounding)."""
    rng = np.random.default_rng(0)
    ph, pw, margin = 60, 70, 12
    reference = cv2.GaussianBlur(
        rng.integers(0, 255, (ph + 24, pw + 24), dtype=np.uint8), (5, 5), 0
    )
    patch = reference[margin + 3 : margin + 3 + ph, margin - 2 : margin - 2 + pw].copy()

    def score(p: Gray) -> npt.NDArray[np.float32]:
        rect = Rectified(
            patch=p, patch_mask=np.full(p.shape, 255, np.uint8), reference=reference,
            reference_mask=np.full(reference.shape, 255, np.uint8), margin_px=margin, level=0,
            gsd_m=1.0, height_m=100.0, prior_east_m=0.0, prior_north_m=0.0,
        )  # fmt: skip
        return axial_correlation(rect)[0]

    a, b = score(patch), score(np.asarray(255 - patch, dtype=np.uint8))
    assert np.allclose(a, b, atol=1e-3 * float(a.max()))
    py, px = np.unravel_index(int(np.argmax(a)), a.shape)
    assert (int(py), int(px)) == (margin + 3, margin - 2)
