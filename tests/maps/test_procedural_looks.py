"""What the procedural maps show: single tree crowns with shadows, species, fields, roofs;
the built-in surface where the texture draws them; coarse levels that agree with fine ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from air_sitl.maps.procedural.canvas import DATES
from air_sitl.maps.procedural.crowns import CELL_M
from air_sitl.maps.procedural.forest import ForestWorld
from air_sitl.maps.procedural.urban import UrbanWorld

GSD = 0.6
# A 307 m square of closed forest (seed 0: no clearing, water or road in it) and a 614 m
# square with a road, tracks, a farmyard, a stream and a lake.
FOREST_XY = (0, 0)
ROAD_XY = (2048, 0)


def _gray(img: np.ndarray) -> np.ndarray:
    return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float32)


def test_forest_is_single_crowns_at_the_density_of_a_stand() -> None:
    world = ForestWorld(0)
    x0, y0 = FOREST_XY
    h = world.objects(x0, y0, 512, GSD, DATES[0])
    area_ha = (512 * GSD) ** 2 / 1e4
    # Crown tops: local maxima of the canopy surface (each tree one, in a 2.4 m window).
    tops = (h == cv2.dilate(h, np.ones((5, 5), np.uint8))) & (h > 5.0)
    per_ha = int(tops.sum()) / area_ha
    cells_per_ha = 1e4 / CELL_M**2
    assert 0.4 * cells_per_ha <= per_ha <= cells_per_ha, f"{per_ha:.0f} crowns per ha"
    cover = float((h > 0).mean())
    assert 0.6 <= cover <= 0.97, f"crown cover {cover:.0%}: a closed stand with gaps"


@pytest.mark.parametrize("date", [0, 1, 2])
def test_crowns_are_lit_toward_the_sun_and_gaps_are_dark(date: int) -> None:
    look = DATES[date]
    world = ForestWorld(0)
    x0, y0 = FOREST_XY
    img = _gray(world.draw(x0, y0, 512, GSD, look))
    h = world.objects(x0, y0, 512, GSD, look)
    # Where the canopy rises toward the sun the crown faces it: brighter than the side away.
    sun_e, sun_n = look.sun_dir()
    gy, gx = np.gradient(h)  # per pixel: x east, y south
    toward_sun = -(gx * sun_e - gy * sun_n)  # the surface falls toward the sun: lit side
    on_crowns = h > 3.0
    lit = img[on_crowns & (toward_sun > 0.5)].mean()
    away = img[on_crowns & (toward_sun < -0.5)].mean()
    assert lit > away + 12.0, f"lit side {lit:.0f}, side away from the sun {away:.0f}"
    # Gaps between crowns (ground, no surface) are in the crowns' shade: darker than crowns.
    gaps = (h == 0) & (cv2.blur((h > 0).astype(np.float32), (15, 15)) > 0.6)
    assert gaps.sum() > 500
    # Bare broadleaf crowns in spring let the light through (thin shadows): 13-15 grey levels
    # from the crowns on this window, whichever trees the clear-cuts and tracks took.
    margin = 10.0 if look.leaf_off else 15.0
    assert img[gaps].mean() < img[on_crowns].mean() - margin


def test_conifer_and_broadleaf_stands_differ() -> None:
    # Over a 2.5 km square at 4.8 m pixels (still drawn crown by crown): dark conifer stands,
    # bright broadleaf stands, in patches of hundreds of metres.
    world = ForestWorld(0)
    img = world.draw(500, -19000, 512, 4.8, DATES[0]).astype(np.float32)
    green = cv2.GaussianBlur(img[:, :, 1], (0, 0), 6.0)  # stand scale (30 m)
    forest = cv2.GaussianBlur(world.objects(500, -19000, 512, 4.8, DATES[0]), (0, 0), 6.0) > 8
    lo, hi = np.percentile(green[forest], [10, 90])
    assert hi - lo > 20.0, f"stands vary by only {hi - lo:.0f} grey levels"


def test_surface_is_open_ground_on_roads_tracks_and_water() -> None:
    world = ForestWorld(0)
    x0, y0 = ROAD_XY
    img = world.draw(x0, y0, 1024, GSD, DATES[0])
    h = world.objects(x0, y0, 1024, GSD, DATES[0])
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    # Asphalt and gravel: grey or brownish, never the green of crowns or meadows.
    hue, sat = hsv[:, :, 0], hsv[:, :, 1]
    bare = ((sat < 40) | (hue < 25)) & (hsv[:, :, 2] > 60)
    bare = cv2.erode(bare.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert bare.sum() > 2000, "the test square shows no road"
    assert (h[bare] < 1.0).mean() > 0.97
    # Lakes and streams: blue.
    water = (hue > 88) & (hue < 125) & (sat > 60)
    water = cv2.erode(water.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    assert water.sum() > 2000, "the test square shows no water"
    assert (h[water] < 1.0).mean() > 0.97


def test_dates_keep_the_trees_and_fell_some_stands() -> None:
    world = ForestWorld(0)
    x0, y0 = 0, 0  # stands clear-cut by date 2 (seed 0)
    h = [world.objects(x0, y0, 1024, GSD, look) for look in DATES]
    for later in (1, 2):
        standing = (h[0] > 0) & (h[later] > 0)
        felled = ((h[0] > 0) & (h[later] == 0)).mean()
        assert felled < 0.25
        corr = np.corrcoef(h[0][standing], h[later][standing])[0, 1]
        assert corr > 0.95, f"crowns moved between dates 0 and {later}: {corr:.2f}"
    assert ((h[0] > 0) & (h[2] == 0)).mean() > 0.02, "no stand felled by date 2"


def test_coarse_forest_levels_agree_with_fine_ones() -> None:
    # Pixels too coarse for crowns (19.2 m) show each stand's mean look and height, over a
    # 922 m square (48 coarse pixels a side). Dates 0 and 1 here: mean colours 3.3 and 3.3
    # apart, correlations 0.95 and 0.94, heights 5 % and 6 % apart; over 1229 m (64 pixels,
    # 2.5 times the CPU) 3.9 and 2.7, 0.92 and 0.93, 1 % and 6 %.
    world = ForestWorld(0)
    n = 48
    for look in (DATES[0], DATES[1]):
        fine = world.draw(32 * 500, 32 * 750, 32 * n, GSD, look)
        coarse = world.draw(500, 750, n, 32 * GSD, look).astype(np.float32)
        reduced = cv2.resize(fine, (n, n), interpolation=cv2.INTER_AREA).astype(np.float32)
        assert np.abs(reduced.mean(axis=(0, 1)) - coarse.mean(axis=(0, 1))).max() < 6.0
        blur = [cv2.GaussianBlur(_gray(a.astype(np.uint8)), (0, 0), 1.5) for a in (reduced, coarse)]
        assert np.corrcoef(blur[0].ravel(), blur[1].ravel())[0, 1] > 0.85
        h_fine = world.objects(32 * 500, 32 * 750, 32 * n, GSD, look).mean()
        h_coarse = world.objects(500, 750, n, 32 * GSD, look).mean()
        assert abs(h_fine - h_coarse) < 0.15 * h_fine


def test_forest_is_deterministic_and_seamless() -> None:
    a = ForestWorld(4).draw(800, 900, 256, GSD, DATES[1])
    b = ForestWorld(4).draw(800, 900, 256, GSD, DATES[1])
    assert np.array_equal(a, b)
    # A tile drawn alone equals the same pixels cut from a larger tile, crown shadows cast
    # from beyond its edge included (bar anti-aliased track edges on its border row).
    big = ForestWorld(4).draw(672, 772, 512, GSD, DATES[1])
    differ = (a != big[128:384, 128:384]).any(axis=2)
    assert differ.mean() < 1e-3 and not differ[2:-2, 2:-2].any()
    h = ForestWorld(4).objects(800, 900, 256, GSD, DATES[1])
    h_big = ForestWorld(4).objects(672, 772, 512, GSD, DATES[1])
    assert np.array_equal(h, h_big[128:384, 128:384])


def test_urban_has_fields_out_of_town_and_varied_roofs() -> None:
    world = UrbanWorld(0)
    kinds: set[str] = set()
    hipped = gabled = flat = 0
    roofs: set[tuple[float, float, float]] = set()
    for kx in range(-20, 20):
        for ky in range(-20, 20):
            blk = world.block(kx, ky)
            kinds.update(kind for _poly, kind in blk.grounds)
            for b in blk.buildings:
                hipped += b.hipped
                gabled += b.gabled and not b.hipped
                flat += not b.gabled
                roofs.add(b.roof)
    crops = {k for k in kinds if k.startswith("crop")}
    assert len(crops) >= 4, "no farm fields at the edge of town"
    assert {"parking", "lawn", "pool", "driveway", "verge"} <= kinds
    assert min(hipped, gabled, flat) > 100
    assert len(roofs) >= 12


def test_urban_roofs_stand_where_houses_are_drawn() -> None:
    world = UrbanWorld(0)
    x0, y0 = 0, 0  # houses, shops and parking in town
    img = world.draw(x0, y0, 512, GSD, DATES[0])
    h = world.objects(x0, y0, 512, GSD, DATES[0])
    hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
    lawn = (hsv[:, :, 0] > 35) & (hsv[:, :, 0] < 85) & (hsv[:, :, 1] > 60)
    # Lawns are low (bar tree crowns): the ground; the surface's roofs are high.
    assert (h[lawn] < 1.0).mean() > 0.6
    roofs = h > 4.0
    assert 0.05 < roofs.mean() < 0.6
    assert not np.array_equal(img[roofs].mean(axis=0), img[~roofs].mean(axis=0))
