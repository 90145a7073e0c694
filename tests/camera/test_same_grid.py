"""A tick rendered over several map dates in one job (issue 34): the geometry and the noise
computed once, every date's frame the bytes its own camera gives, whatever thread renders it."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest
from georef_helpers import HOME

from air_sitl.camera.bridge import CameraBridge
from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state, render_camera_frame
from air_sitl.camera.same_grid import GridCamera, GridFrames, same_grid
from air_sitl.frames import ned2geodetic
from air_sitl.maps.base import MapSource
from air_sitl.maps.open import open_map
from air_sitl.state import CameraFrame, GeoPoint, SimSample, mission_sample

SMALL = CameraModel(width_px=320, height_px=240)
EFFECTS = replace(SMALL, effects=CameraEffects(enabled=("blur", "vignette", "distortion")))


def _samples(n: int) -> list[SimSample]:
    """A pass, rolling and turning."""
    out = []
    for i in range(n):
        lat, lon, _ = ned2geodetic(4.0 * i, 1.0 * i, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        roll = 0.3 * math.sin(i / 2)
        state = pose_state(
            lat,
            lon,
            HOME.alt_amsl_m + 200.0,
            alt_agl_m=200.0,
            roll_rad=roll,
            yaw_rad=0.1 * i,
            sim_time_ns=20_000_000 * i,
        )
        out.append(mission_sample(state))
    return out


_MAPS: dict[tuple[str, int], MapSource] = {}


def _renderers(kind: str, camera: CameraModel, dates: tuple[int, ...]) -> list[Renderer]:
    """New renderers (their own noise) over the maps of ``dates`` (opened once: pure)."""
    for d in dates:
        if (kind, d) not in _MAPS:
            _MAPS[kind, d] = open_map(kind, HOME, seed=3, date=d)
    return [Renderer(_MAPS[kind, d], camera, seed=7) for d in dates]


def _fields(frame: CameraFrame) -> tuple[object, ...]:
    return (frame.index, frame.sim_time_ns, frame.jpeg, frame.map_xy_px, frame.nodata_fraction)


@pytest.mark.parametrize("camera", [SMALL, EFFECTS], ids=["pinhole", "effects"])
def test_a_tick_over_the_dates_gives_each_date_its_own_frame(camera: CameraModel) -> None:
    samples = _samples(6)
    grid = GridFrames(_renderers("urban", camera, (0, 1, 2)))
    assert grid.shared  # one grid: the geometry and the noise computed once
    got = [grid.render(s, i) for i, s in enumerate(samples)]
    for k, alone in enumerate(_renderers("urban", camera, (0, 1, 2))):
        want = [render_camera_frame(alone, s, i) for i, s in enumerate(samples)]
        assert [_fields(t[k]) for t in got] == [_fields(f) for f in want], k
    assert got[3][0].jpeg != got[3][1].jpeg  # the dates do differ
    assert got[-1][0].map_xy_px != got[0][0].map_xy_px


def test_maps_of_other_grids_are_rendered_each_alone() -> None:
    urban, forest = _renderers("urban", SMALL, (0,))[0], _renderers("forest", SMALL, (0,))[0]
    assert same_grid(urban, forest)  # other worlds on one lattice: one geometry
    assert not same_grid(urban, Renderer(urban.map, SMALL, seed=8))  # other noise
    assert not same_grid(urban, Renderer(urban.map, EFFECTS, seed=7))  # another camera
    away = GeoPoint(lat_deg=HOME.lat_deg + 0.05, lon_deg=HOME.lon_deg, alt_amsl_m=HOME.alt_amsl_m)
    elsewhere = Renderer(open_map("urban", away, seed=3), SMALL, seed=7)
    assert not same_grid(urban, elsewhere)  # another lattice
    grid = GridFrames([urban, elsewhere])
    assert not grid.shared
    sample = _samples(2)[1]
    got = grid.render(sample, 5)
    alone = [_renderers("urban", SMALL, (0,))[0], Renderer(elsewhere.map, SMALL, seed=7)]
    assert [_fields(f) for f in got] == [_fields(render_camera_frame(r, sample, 5)) for r in alone]


def test_the_grid_camera_hands_ticks_out_in_order_on_one_pool() -> None:
    samples = _samples(8)
    bridges = [CameraBridge(r, workers=2) for r in _renderers("forest", SMALL, (0, 2))]
    camera = GridCamera(bridges, workers=2, max_pending=3)
    got = []
    for i, s in enumerate(samples):
        camera.submit(s, i)
        got.extend(camera.ready())
    got.extend(camera.flush())
    camera.close()
    assert [[f.index for f in tick] for tick in got] == [[i, i] for i in range(8)]
    for k, alone in enumerate(_renderers("forest", SMALL, (0, 2))):
        want = [render_camera_frame(alone, s, i).jpeg for i, s in enumerate(samples)]
        assert [tick[k].jpeg for tick in got] == want
