"""Procedural maps: dates that differ and are misregistered within bounds, ORB texture,
determinism, bounded memory."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from georef_helpers import HOME

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.cli import main
from air_sitl.frames import ned2geodetic
from air_sitl.maps.open import open_map
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.survey import PROCESSING


def _state(
    alt: float, north_m: float = 0.0, east_m: float = 0.0, roll: float = 0.0, yaw: float = 0.3
):  # type: ignore[no-untyped-def]
    lat, lon, _ = ned2geodetic(north_m, east_m, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    return pose_state(lat, lon, HOME.alt_amsl_m + alt, alt_agl_m=alt, roll_rad=roll, yaw_rad=yaw)


def _gray(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)


@functools.cache
def _date_frame(kind: str, date: int) -> np.ndarray:
    """The frame at 300 m over ``kind`` at ``date``, from a map and renderer of its own:
    rendered once for the two date pairs below that read it."""
    cam = CameraModel(noise_sigma=0.0)
    frame = Renderer(open_map(kind, HOME, seed=3, date=date), cam).render(
        _state(300.0, 120.0, -80.0)
    )
    frame.flags.writeable = False
    return frame


@pytest.mark.parametrize("kind", ["urban", "forest"])
@pytest.mark.parametrize(("d0", "d1"), [(0, 1), (0, 2), (1, 2)])
def test_dates_differ_and_are_misregistered_within_bounds(kind: str, d0: int, d1: int) -> None:
    """Each date is its own survey: the orthophotos are misregistered against each other
    like real ones (a shift of 0.5-1.5 m plus a local warp below 1 m), never more."""
    cam = CameraModel(noise_sigma=0.0)
    a, b = _date_frame(kind, d0), _date_frame(kind, d1)
    differ = (np.abs(a.astype(np.int16) - b.astype(np.int16)).max(axis=2) > 20).mean()
    assert differ >= 0.10, f"only {differ:.1%} of pixels differ"
    window = cv2.createHanningWindow((a.shape[1], a.shape[0]), cv2.CV_32F)
    (dx, dy), _response = cv2.phaseCorrelate(_gray(a), _gray(b), window)
    gsd_m = 2.0 * 300.0 * math.tan(math.radians(cam.hfov_deg / 2.0)) / cam.width_px
    off_m = math.hypot(dx, dy) * gsd_m
    # The surveys' shift and warp, plus a pixel for what the sun and season move (crowns lit
    # on another side shift their bright centres a little).
    bound = sum(PROCESSING[d].shift_m + PROCESSING[d].warp_m for d in (d0, d1)) + gsd_m
    assert off_m <= bound, f"dates misregistered by {off_m:.2f} m (at most {bound:.1f} m)"
    if d0 == 0:  # date 0 is the reference survey: the others are off it by their shift
        assert off_m >= 0.3, f"dates {d0} and {d1} registered to {off_m:.2f} m: no misregistration"


@pytest.mark.parametrize(("kind", "minimum"), [("urban", 300), ("forest", 150)])
def test_orb_finds_enough_keypoints_at_300m(kind: str, minimum: int) -> None:
    orb = cv2.ORB_create()
    for seed, (n, e) in enumerate([(0.0, 0.0), (900.0, -400.0), (-1500.0, 2200.0)]):
        renderer = Renderer(open_map(kind, HOME, seed=seed), CameraModel())
        jpeg, _xy = renderer.frame_jpeg(_state(300.0, n, e), seed)
        frame = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_GRAYSCALE)
        count = len(orb.detect(frame, None))
        assert count >= minimum, f"{kind} seed {seed}: {count} ORB keypoints"


def test_same_seed_same_bytes_other_seed_other_bytes() -> None:
    cam = CameraModel()
    state = _state(250.0, 50.0, 50.0, roll=0.2)
    a = Renderer(open_map("urban", HOME, seed=7), cam, seed=1).frame_jpeg(state, 5)
    b = Renderer(open_map("urban", HOME, seed=7), cam, seed=1).frame_jpeg(state, 5)
    c = Renderer(open_map("urban", HOME, seed=8), cam, seed=1).frame_jpeg(state, 5)
    d = Renderer(open_map("urban", HOME, seed=7), cam, seed=1).frame_jpeg(state, 6)
    assert a == b
    assert a[0] != c[0]
    assert a[0] != d[0] and a[1] == d[1]  # noise follows the frame index; geometry does not


def test_tiles_are_seamless_and_independent_of_order() -> None:
    m1 = ProceduralMap("forest", HOME, seed=2)
    m2 = ProceduralMap("forest", HOME, seed=2)
    big = m1.read_bgr(1000, 2000, 700, 600)
    parts = [m2.read_bgr(1000 + x, 2000 + y, 350, 300) for y in (300, 0) for x in (350, 0)]
    stitched = np.vstack([np.hstack([parts[3], parts[2]]), np.hstack([parts[1], parts[0]])])
    assert np.array_equal(big, stitched)


def test_memory_stays_bounded_on_a_long_flight() -> None:
    cap = 24 * 1024 * 1024
    m = ProceduralMap("urban", HOME, seed=1, cache_bytes=cap)
    renderer = Renderer(m, CameraModel(noise_sigma=0.0))
    put = m._cache.put
    stored = []  # bytes of every tile put in the cache

    def counting_put(key: tuple[int, int, int], tile: np.ndarray) -> None:
        stored.append(tile.nbytes)
        put(key, tile)

    m._cache.put = counting_put  # type: ignore[method-assign]
    for i in range(45):  # 4.5 km east at 300 m: new ground all the way
        renderer.render(_state(300.0, 0.0, 100.0 * i, yaw=math.pi / 2))
        assert m.cache_bytes <= cap
    assert m.cache_bytes > cap // 2  # the cache was really used
    # and evicted: the flight drew more ground than the cache holds (a third more; it is full
    # by 3 km, then each new tile evicts one)
    assert sum(stored) > cap, sum(stored) / cap


def test_map_make_writes_the_procedural_pixels(tmp_path: Path) -> None:
    out = tmp_path / "u.tif"
    origin = f"{HOME.lat_deg},{HOME.lon_deg}"
    code = main(
        [
            "map",
            "make",
            "urban",
            "--out",
            str(out),
            "--seed",
            "4",
            "--size-m",
            "600",
            "450",
            "--date",
            "1",
            "--origin",
            origin,
            "--lossless",
        ]
    )
    assert code == 0
    home0 = type(HOME)(lat_deg=HOME.lat_deg, lon_deg=HOME.lon_deg, alt_amsl_m=0.0)
    tif = open_map(str(out), home0)
    proc = ProceduralMap("urban", home0, seed=4, date=1)
    assert tif.georef.crs == proc.georef.crs == "EPSG:32635"
    # Centred on the origin, on the same lattice: the grids differ by whole pixels.
    x_t, y_t = tif.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    x_p, y_p = proc.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    assert abs(x_t - 500) <= 0.5 and abs(y_t - 375) <= 0.5
    c0, r0 = round(x_p - x_t), round(y_p - y_t)
    assert abs(x_t + c0 - x_p) < 1e-6 and abs(y_t + r0 - y_p) < 1e-6
    assert np.array_equal(
        tif.read_level(0, 0, 0, 1000, 750)[:, :, :3], proc.read_bgr(c0, r0, 1000, 750)
    )
    cam = CameraModel(noise_sigma=0.0)
    state = pose_state(HOME.lat_deg, HOME.lon_deg, 180.0, alt_agl_m=180.0, yaw_rad=0.5)
    a = Renderer(tif, cam).render(state).astype(np.int16)
    b = Renderer(proc, cam).render(state).astype(np.int16)
    assert np.abs(a - b).mean() < 0.05
    assert tif.num_levels >= 3
    assert len(tif._src.overviews(1)) >= 1  # type: ignore[attr-defined]


def test_direct_coarse_levels_match_reduced_level_0() -> None:
    # Level 3 is drawn directly at level 2's resolution; it must look like level 0 reduced.
    direct = ProceduralMap("forest", HOME, seed=6)
    reduced = ProceduralMap("forest", HOME, seed=6)
    reduced._native_tile = lambda *args: None  # type: ignore[method-assign]
    a = direct.read_level(3, 20, 20, 128, 128)[:, :, :3].astype(np.float32)
    b = reduced.read_level(3, 20, 20, 128, 128)[:, :, :3].astype(np.float32)
    assert np.abs(a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))).max() < 5.0
    ga = cv2.GaussianBlur(_gray(a.astype(np.uint8)), (0, 0), 2.0)
    gb = cv2.GaussianBlur(_gray(b.astype(np.uint8)), (0, 0), 2.0)
    assert np.corrcoef(ga.ravel(), gb.ravel())[0, 1] > 0.8
