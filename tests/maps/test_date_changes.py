"""Change over the years between the procedural maps' surveys: new streets and parking lots in
town, logging tracks to the forest's clear-cuts (none at the reference date, more seven years
on than three, kept once built, flat ground in the built-in surface); autumn turning the
broadleaves while the conifers stay green; spring's bare crowns, dead grass and high water."""

from __future__ import annotations

import math

import cv2
import numpy as np
from georef_helpers import HOME

from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.canvas import DATES
from air_sitl.maps.procedural.forest import SPRING_POND_FILL, ForestWorld
from air_sitl.maps.procedural.forest_cuts import clear_cut, logging_tracks
from air_sitl.maps.procedural.urban import UrbanWorld
from air_sitl.maps.procedural.urban_blocks import Block
from air_sitl.maps.procedural.yeargap import ponds

GSD = 0.5
BLOCKS = range(-12, 12)  # 24 x 24 blocks of 105 m: about 6 km2


def _paving(block: Block) -> list[tuple[tuple[tuple[float, float], ...], str]]:
    return [(poly, kind) for poly, kind in block.grounds if kind in ("newroad", "newlot")]


def test_new_streets_and_lots_appear_over_the_years_and_stay() -> None:
    world = UrbanWorld(3)
    found: list[dict[str, int]] = []
    for d in range(len(DATES)):
        kinds = {"newroad": 0, "newlot": 0}
        for ky in BLOCKS:
            for kx in BLOCKS:
                for _poly, kind in _paving(world.block(kx, ky, d)):
                    kinds[kind] += 1
                if d == 2 and (paved := _paving(world.block(kx, ky, 1))):
                    # Built by 2012: the same street or lot, at the same place, in 2016.
                    assert set(paved) <= set(_paving(world.block(kx, ky, 2))), (kx, ky)
        found.append(kinds)
    assert found[0] == {"newroad": 0, "newlot": 0}, "new paving at the reference date"
    for kind in ("newroad", "newlot"):
        assert 0 < found[1][kind] < found[2][kind], (kind, found)


def _inside(world: UrbanWorld, poly: tuple[tuple[float, float], ...], x0: int, y0: int, n: int):  # type: ignore[no-untyped-def]
    """Pixels of a window (x0, y0, n) whose centres lie 1 m inside a layout-frame box."""
    e = (x0 + np.arange(n) + 0.5)[None, :] * GSD
    north = -(y0 + np.arange(n) + 0.5)[:, None] * GSD
    u = world.c * e + world.s * north
    v = -world.s * e + world.c * north
    us, vs = [p[0] for p in poly], [p[1] for p in poly]
    return (u > min(us) + 1) & (u < max(us) - 1) & (v > min(vs) + 1) & (v < max(vs) - 1)


def test_the_surface_is_flat_ground_on_a_new_street() -> None:
    """Houses and trees stood where a new street runs; the built-in DSM has them gone."""
    world = UrbanWorld(3)
    cleared = 0
    for ky in BLOCKS:
        for kx in BLOCKS:
            streets = [p for p, kind in _paving(world.block(kx, ky, 2)) if kind == "newroad"]
            if not streets:
                continue
            u0, v0, u1, v1 = world.block(kx, ky, 0).bounds
            ce, cn = world.to_world([((u0 + u1) / 2, (v0 + v1) / 2)])[0]
            n = 300
            x0, y0 = math.floor(ce / GSD) - n // 2, math.floor(-cn / GSD) - n // 2
            road = _inside(world, streets[0], x0, y0, n)
            assert road.sum() > 500
            after = world.objects(x0, y0, n, GSD, DATES[2])
            assert float(after[road].max()) < 0.05, f"block {kx},{ky}: an object on the street"
            before = world.objects(x0, y0, n, GSD, DATES[0])
            cleared += float(before[road].max()) > 2.0
    assert cleared >= 2, "no new street was cut where buildings or trees stood"


def test_logging_tracks_lead_to_the_cuts_and_stay() -> None:
    box = (-3000.0, -3000.0, 3000.0, 3000.0)
    tracks = [logging_tracks(3, *box, d) for d in range(len(DATES))]
    assert tracks[0] == []
    assert 0 < len(tracks[1]) < len(tracks[2])
    for track in tracks[1]:
        assert track in tracks[2]
    # The surface is open ground along a track where trees stood before it was built.
    world = ForestWorld(3)
    opened = 0
    for track in tracks[2][:12]:
        e, n = track[len(track) // 2]
        x0, y0 = math.floor(e / GSD) - 32, math.floor(-n / GSD) - 32
        after = world.objects(x0, y0, 64, GSD, DATES[2])[28:37, 28:37]
        assert float(after.max()) < 0.05, "a crown on a logging track"
        opened += float(world.objects(x0, y0, 64, GSD, DATES[0])[28:37, 28:37].max()) > 2.0
    assert opened >= 3, "no track was cut through standing trees"


def _hue_deg(pixels: np.ndarray) -> np.ndarray:
    hsv = cv2.cvtColor(pixels.reshape(-1, 1, 3), cv2.COLOR_BGR2HSV)
    return hsv[:, 0, 0].astype(float) * 2.0


def test_autumn_turns_the_broadleaves_and_leaves_the_conifers_green() -> None:
    world = ForestWorld(0)
    x0, y0, n = 0, 0, 512
    hues: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for d in (0, 1):
        g = world._ground(x0, y0, n, GSD, DATES[d])
        # Well inside crowns: the survey's misregistration (under 2 m) stays on its kind.
        core = np.ones((9, 9), np.uint8)
        on = g.cover > 0.5
        con = cv2.erode((on & (g.conifer > 0.5)).astype(np.uint8), core) > 0
        dec = cv2.erode((on & (g.conifer < 0.5)).astype(np.uint8), core) > 0
        assert con.sum() > 5000 and dec.sum() > 5000
        img = ProceduralMap("forest", HOME, seed=0, date=d, gsd_m=GSD).render_abs(x0, y0, n)
        hues[d] = (_hue_deg(img[con]), _hue_deg(img[dec]))
    summer_con, summer_dec = (float(np.median(h)) for h in hues[0])
    autumn_con, autumn_dec = hues[1]
    # Conifers: green (between yellow-green and cyan) in both surveys.
    assert 90.0 < summer_con < 160.0
    assert 90.0 < float(np.median(autumn_con)) < 160.0, float(np.median(autumn_con))
    # Broadleaves: green in summer; in autumn yellow, orange and brown, some still green.
    assert summer_dec > 75.0
    assert float(np.median(autumn_dec)) < 60.0
    assert 0.05 < float((autumn_dec > 75.0).mean()) < 0.5
    assert float((autumn_dec < 45.0).mean()) > 0.2


def test_town_conifers_stay_green_in_autumn() -> None:
    world = UrbanWorld(0)
    x0, y0, n = -600, -600, 1200
    img = ProceduralMap("urban", HOME, seed=0, date=1, gsd_m=GSD).render_abs(x0, y0, n)
    crowns: dict[bool, list[np.ndarray]] = {True: [], False: []}
    for ky in range(-4, 4):
        for kx in range(-4, 4):
            for c, r, ci, born in world.block(kx, ky, 1).trees:
                e, north = world.to_world([c])[0]
                col, row = math.floor(e / GSD) - x0, math.floor(-north / GSD) - y0
                if born <= 1 and r > 2.5 and 2 <= col < n - 2 and 2 <= row < n - 2:
                    # The crown's middle 3 x 3 pixels (its lean and the shift stay under 2 m).
                    crowns[ci == 2].append(img[row - 1 : row + 2, col - 1 : col + 2])
    conifer = _hue_deg(np.concatenate(crowns[True]).reshape(-1, 3))
    broadleaf = _hue_deg(np.concatenate(crowns[False]).reshape(-1, 3))
    assert len(conifer) > 200 and len(broadleaf) > 400
    assert 90.0 < float(np.median(conifer)) < 160.0, float(np.median(conifer))
    assert float(np.median(broadleaf)) < 60.0, float(np.median(broadleaf))


def test_new_paving_is_the_same_whichever_window_draws_it() -> None:
    """A logging track and a new street: a window drawn alone shows them as the same pixels
    cut from a window three times its size around it (the forest's survey as a whole; in
    town the street's own pixels of the scene: the old main roads' long edge lines, drawn
    from window edge to window edge, may differ by a grey level where their anti-aliasing
    rounds otherwise, and the survey's compression spreads that over its blocks)."""
    track = logging_tracks(3, -3000.0, -3000.0, 3000.0, 3000.0, 2)[0]
    e, n = track[len(track) // 2]
    x, y = math.floor(e / GSD) - 128, math.floor(-n / GSD) - 128
    forest = ProceduralMap("forest", HOME, seed=3, date=2, gsd_m=GSD)
    big = forest.render_abs(x - 256, y - 256, 768)
    small = ProceduralMap("forest", HOME, seed=3, date=2, gsd_m=GSD).render_abs(x, y, 256)
    assert np.array_equal(big[256:512, 256:512], small)
    world = UrbanWorld(3)
    checked = 0
    for ky in BLOCKS[8:16]:
        for kx in BLOCKS[8:16]:
            streets = [p for p, kind in _paving(world.block(kx, ky, 2)) if kind == "newroad"]
            if not streets:
                continue
            u0, v0, u1, v1 = world.block(kx, ky, 2).bounds
            ce, cn = world.to_world([((u0 + u1) / 2, (v0 + v1) / 2)])[0]
            x, y = math.floor(ce / GSD) - 128, math.floor(-cn / GSD) - 128
            road = _inside(world, streets[0], x, y, 256)
            big = UrbanWorld(3).draw(x - 256, y - 256, 768, GSD, DATES[2])[256:512, 256:512]
            small = UrbanWorld(3).draw(x, y, 256, GSD, DATES[2])
            assert road.sum() > 1000
            assert np.array_equal(big[road], small[road]), (kx, ky)
            checked += 1
    assert checked > 0


def test_spring_bares_the_broadleaves_brown_and_cuts_show_dead_grass() -> None:
    """The April survey: bare broadleaf crowns are grey-brown over the litter, not mauve
    under the survey's cool white balance; young growth on a cut felled by 2012 is last
    year's dead grass, straw (red at least blue), where summer's would be green."""
    world = ForestWorld(0)
    g = world._ground(0, 0, 512, GSD, DATES[2])
    img = ProceduralMap("forest", HOME, seed=0, date=2, gsd_m=GSD).render_abs(0, 0, 512)
    dec = cv2.erode(((g.cover > 0.5) & (g.conifer < 0.5)).astype(np.uint8), np.ones((9, 9)))
    hsv = cv2.cvtColor(img[dec > 0].reshape(-1, 1, 3), cv2.COLOR_BGR2HSV)[:, 0, :]
    assert dec.sum() > 5000
    mauve = (hsv[:, 0].astype(float) * 2.0 > 250.0) & (hsv[:, 1] > 25)
    assert float(mauve.mean()) < 0.02
    assert 20.0 < float(np.median(hsv[:, 0])) * 2.0 < 75.0  # orange-brown to olive
    i, j = next((i, j) for i in range(-6, 6) for j in range(-6, 6) if clear_cut(0, i, j).at == 1)
    e, n = clear_cut(0, i, j).centre
    x0, y0 = math.floor(e / GSD) - 64, math.floor(-n / GSD) - 64
    g = world._ground(x0, y0, 128, GSD, DATES[2])
    on_cut = cv2.erode((g.cut > 0.3).astype(np.uint8), np.ones((9, 9))) > 0
    assert on_cut.sum() > 4000 and 0.5 < float(g.cut[on_cut].mean()) < 0.8  # growing again
    b, gr, r = (
        ProceduralMap("forest", HOME, seed=0, date=2, gsd_m=GSD)
        .render_abs(x0, y0, 128)[on_cut]
        .astype(float)
        .mean(axis=0)
    )
    assert r >= b + 8.0 and r > gr - 6.0, (b, gr, r)


def test_spring_high_water_fills_more_hollows() -> None:
    """Ponds: the same hollows every survey; the spring survey's high water fills shallower
    ones too, none on the reference date."""
    low, high = (ponds(0, DATES[2], 0, 0, 1024, 2.4, f) > 0.5 for f in (0.0, SPRING_POND_FILL))
    assert not ponds(0, DATES[0], 0, 0, 256, 2.4, SPRING_POND_FILL).any()
    assert bool(np.all(high[low])) and float(high.mean()) > 2.0 * float(low.mean()) > 0.01
