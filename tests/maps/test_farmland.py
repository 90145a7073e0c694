"""The ``farmland`` world: deterministic, window-independent, with relief, with what real year
gaps change (crops rotating, fields bare one year and green the next, pivots idle, water that
grows and dries), and its AIR-style scenarios parse and fly."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from air_sitl.cli import main
from air_sitl.dataset.scenarios import (
    AIR_SCENARIOS,
    FARMLAND_SCENARIOS,
    ScenarioStats,
    missions_dir,
    parse_scenarios,
    stats_table,
)
from air_sitl.maps.base import MapError
from air_sitl.maps.dates import date_fields
from air_sitl.maps.open import default_map_for_plan, open_map, open_surface
from air_sitl.maps.procedural import ProceduralMap, parse_date
from air_sitl.maps.procedural.canvas import DATES, FARMLAND_DATES, dates_of
from air_sitl.maps.procedural.farmland import FarmlandWorld, _rows
from air_sitl.maps.procedural.farmland_built import BUILDING, TREES, WATER
from air_sitl.maps.procedural.farmland_layout import (
    CORN,
    GRASS,
    SOY,
    crop_in,
    drainage,
    fields,
    grid,
)
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=40.8968, lon_deg=-97.6227, alt_amsl_m=509.0)  # the A* plans' home
REPO = Path(__file__).resolve().parents[2]


def _map(date: int, seed: int = 0) -> ProceduralMap:
    m = open_map("farmland", HOME, seed=seed, date=date)
    assert isinstance(m, ProceduralMap)
    return m


def test_same_seed_and_date_same_bytes_other_date_other_bytes() -> None:
    a = _map(1, seed=4).render_abs(-8000, -90000, 256)
    b = _map(1, seed=4).render_abs(-8000, -90000, 256)
    assert a.tobytes() == b.tobytes()
    assert a.tobytes() != _map(2, seed=4).render_abs(-8000, -90000, 256).tobytes()
    assert a.tobytes() != _map(1, seed=5).render_abs(-8000, -90000, 256).tobytes()


@pytest.mark.parametrize("gsd_m", [0.6, 2.4, 19.2])
def test_a_pixel_is_the_same_whatever_window_draws_it(gsd_m: float) -> None:
    """The scene (before the survey's camera) at level 0 and at the direct coarse levels."""
    m = _map(2)
    world = m.world
    x0, y0 = m.origin_abs_px[0] >> 0, m.origin_abs_px[1]
    x0, y0 = round(x0 * 0.6 / gsd_m) + 4000, round(y0 * 0.6 / gsd_m) + 4000
    big = world.draw(x0, y0, 320, gsd_m, m.date)
    small = world.draw(x0 + 150, y0 + 90, 120, gsd_m, m.date)
    assert np.array_equal(big[90:210, 150:270], small)


def test_the_survey_of_a_tile_equals_the_same_pixels_of_a_larger_window() -> None:
    m = _map(1)
    ox, oy = m.origin_abs_px
    big = m.render_abs(ox + 5000, oy + 5000, 512)
    small = m.render_abs(ox + 5000 + 256, oy + 5000 + 128, 256)
    assert np.array_equal(big[128:384, 256:], small)


def _farmstead_window(m: ProceduralMap) -> tuple[int, int]:
    """A 256-pixel window (absolute lattice) holding buildings, near home."""
    world = m.world
    ox, oy = m.origin_abs_px
    for j in range(0, 10240, 256):
        for i in range(0, 10240, 256):
            codes = world.land_cover(ox + i, oy + j, 64, 9.6, m.date)  # type: ignore[union-attr]
            if (codes == TREES).any():
                x, y = (ox + i) * 16, (oy + j) * 16
                for dy in range(0, 64 * 16, 256):
                    for dx in range(0, 64 * 16, 256):
                        fine = world.land_cover(x + dx, y + dy, 256, 0.6, m.date)  # type: ignore[union-attr]
                        if (fine == BUILDING).sum() > 200:
                            return x + dx, y + dy
    raise AssertionError("no farmstead within the map's nominal window")


def test_the_builtin_surface_raises_trees_and_buildings_over_rolling_terrain() -> None:
    m = _map(0)
    surface = open_surface("builtin", m)
    assert surface is not None
    x, y = _farmstead_window(m)
    heights = m.world.objects(x, y, 256, 0.6, m.date)
    codes = m.world.land_cover(x, y, 256, 0.6, m.date)  # type: ignore[union-attr]
    assert float(heights[codes == BUILDING].mean()) > 4.0
    assert float(heights.max()) > 8.0  # bins and shelterbelt trees
    # Rolling terrain: metres over kilometres, home's elevation at home.
    hx, hy = m.home_px
    assert surface.terrain_at_map_px(hx, hy) == pytest.approx(HOME.alt_amsl_m, abs=0.05)
    far = [surface.terrain_at_map_px(hx + k * 1500.0, hy) for k in range(-3, 4)]
    assert float(np.ptp(far)) > 2.0


def test_crops_rotate_and_field_looks_change_between_the_years() -> None:
    g = grid(0, -20000, -80000, 512, 20.0)
    years = {}
    for year in (2009, 2012, 2016):
        f = fields(0, g, year, 20.0)
        years[year] = crop_in(0, f.key, year)
    corn_soy = np.isin(years[2009], (CORN, SOY))
    assert 0.5 < float(corn_soy.mean()) < 0.95
    changed_3 = float((years[2009] != years[2012]).mean())
    changed_7 = float((years[2009] != years[2016]).mean())
    assert changed_3 > 0.4 and changed_7 > 0.4
    # Alternate years of corn and soybeans: most fields grow the other one a year later.
    f = fields(0, g, 2010, 20.0)
    assert float((crop_in(0, f.key, 2010) != crop_in(0, f.key, 2009))[corn_soy].mean()) > 0.6


def test_water_varies_from_year_to_year() -> None:
    """Open water (potholes, the creek) over a 20 km square at each survey: its share differs
    between the years by more than a third of the smaller one, water is found in all, and
    most of the reference survey's water is water again (the basins keep several years'
    water: in the NAIP series of one North Dakota quad 1.0-1.7 times the area, 94-99 % kept)."""
    water = []
    for date in (0, 1, 2):
        m = _map(date, seed=1)
        codes = m.world.land_cover(-500, -2250, 512, 38.4, m.date)  # type: ignore[union-attr]
        water.append(codes == WATER)
    shares = [float(w.mean()) for w in water]
    assert min(shares) > 0.0005
    assert max(shares) > 1.3 * min(shares), shares
    for later in water[1:]:
        assert float((water[0] & later).sum() / water[0].sum()) > 0.8


def test_farmland_is_surveyed_in_the_growing_season_as_naip() -> None:
    """Farmland's own calendar: the reference June survey, then 3 and 7 years later in July
    and August (leaf-on); urban and forest keep the common one. Maps, reports and parsing
    name the world's dates."""
    assert FARMLAND_DATES[0] == DATES[0] and dates_of("urban") == DATES
    assert [d.label[:4] for d in FARMLAND_DATES] == ["2009", "2012", "2016"]
    assert all(6 <= int(d.label[5:7]) <= 8 and d.season == "summer" for d in FARMLAND_DATES)
    m = _map(2)
    assert m.describe()["date"] == FARMLAND_DATES[2].label
    assert date_fields(m.describe())["dates"] == [d.label for d in FARMLAND_DATES]
    assert parse_date(FARMLAND_DATES[1].label, "farmland") == FARMLAND_DATES[1]
    with pytest.raises(MapError, match="farmland"):
        parse_date(DATES[1].label, "farmland")  # October is not a farmland survey


def _grey(img: np.ndarray) -> np.ndarray:
    return img.astype(np.float64) @ np.array([0.114, 0.587, 0.299])


def test_what_persists_inside_fields_with_the_years_sign() -> None:
    """Grassed waterways stay grass every survey; the row direction of most fields is the
    reference year's; crops in the swales are darker (greener) than off them in the dry year
    (2012, seed 0: wetness 0.33) and paler (drowned out) in the wet one (2016: 0.65)."""
    world = FarmlandWorld(0)
    gsd, n = 2.4, 384
    ratios: dict[int, list[float]] = {1: [], 2: []}
    drawn = 0
    for x0, y0 in ((0, 0), (3000, -2000), (-4000, 5000)):
        swale, waterway = drainage(0, x0, y0, n, gsd)
        assert 0.003 < float((waterway > 0.5).mean()) < 0.06
        kept = waterway > 0.9  # drawn where no pivot, pond, road or farmstead lies
        for d, look in enumerate(FARMLAND_DATES):
            code = world.land_cover(x0, y0, n, gsd, look)
            if d == 0:
                kept &= code == GRASS
                drawn += int(kept.sum())
                continue
            assert int((code[kept] != GRASS).sum()) <= 0.05 * int(kept.sum()), look.label
            grey = _grey(world.draw(x0, y0, n, gsd, look))
            crop = np.isin(code, (CORN, SOY)) & (waterway < 0.1)
            ratios[d].append(grey[crop & (swale > 0.6)].mean() / grey[crop & (swale < 0.05)].mean())
    assert drawn > 500
    assert np.mean(ratios[1]) < 0.97 and np.mean(ratios[2]) > 1.02, ratios
    # Rows: the axis of the row stripes (structure tensor per pixel) in 2009 and 2016.
    g = grid(0, 2000, -3000, 512, 0.6)
    axes = []
    for year in (2009, 2016):
        f = fields(0, g, year, 0.6)
        stripes = _rows(0, g, f, year, 0.6, np.zeros(f.fid.shape, np.int64))
        gy, gx = np.gradient(stripes)
        inner = (f.edge_m > 15.0) & ~np.isfinite(f.pivot_r_m)
        axes.append((np.abs(gx) > np.abs(gy), inner))
    both = axes[0][1] & axes[1][1]
    assert float(both.mean()) > 0.3
    assert float((axes[0][0] == axes[1][0])[both].mean()) > 0.75


def test_scenarios_groups_and_the_air_table() -> None:
    folder = missions_dir(str(REPO / "missions"))
    assert parse_scenarios("all", folder) == [*AIR_SCENARIOS, *FARMLAND_SCENARIOS]
    assert parse_scenarios("air", folder) == list(AIR_SCENARIOS)
    assert parse_scenarios("farmland,UC-200", folder) == [*FARMLAND_SCENARIOS, "UC-200"]
    assert FARMLAND_SCENARIOS == ("AL-200", "AL-300", "AR-200", "AR-300", "AC-200", "AC-300")
    assert default_map_for_plan("missions/AC-200.plan") == "farmland"
    stats = [
        ScenarioStats(scenario=n, images=1000, distance_m=300.0, mission_completed=True,
                      sim_time_s=100.0)
        for n in ("UC-200", "AC-200", "FC-300")
    ]  # fmt: skip
    rows = {r[0]: r for r in stats_table(stats)}
    # The total compares AIR's rows alone with the paper; farmland has its own, no paper.
    assert rows["total"][1] == "2000" and rows["total"][3] == str(3422 + 3450)
    assert rows["total farmland"][1] == "1000" and rows["total farmland"][3] == ""
    assert rows["AC-200"][3] == ""


@pytest.mark.integration
def test_ac_200_flies_over_farmland(tmp_path: Path) -> None:
    out = tmp_path / "ac"
    argv = ["fly", str(REPO / "missions" / "AC-200.plan"), "--air-start"]
    argv += ["--max-sim-time", "40", "--out", str(out)]
    main(argv)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["map"]["kind"] == "farmland"
    assert manifest["frame_count"] > 50
