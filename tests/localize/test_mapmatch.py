"""``mapmatch``: real frames of a short flight over the urban map (date 1) against date 0.

One real flight (the first 12 s of UC-200's circle, banked about 9 degrees: the session's
``uc200_date1_start``, shared with test_fused), run through the offline driver as ``air-sitl
localize`` runs it; no mocks.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from shared_builds import copy_archive
from short_plans import write_short_plan

from air_sitl.camera.model import CameraModel
from air_sitl.cli import main
from air_sitl.dataset.reader import open_archive
from air_sitl.eval import evaluate
from air_sitl.frames import ned2geodetic
from air_sitl.localize.archive import (
    LocalizeRun,
    context_of,
    observations,
    read_rows,
    run_archive,
    run_method,
)
from air_sitl.localize.base import Estimate, Observation
from air_sitl.localize.mapmatch import MapMatchLocalizer, open_reference
from air_sitl.localize.mapmatch_core import MapMatcher
from air_sitl.maps import open_map
from air_sitl.maps.procedural import ProceduralMap
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def flight(uc200_date1_start: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The session's shared flight (conftest), copied: these tests write estimates into it."""
    return copy_archive(
        uc200_date1_start, tmp_path_factory.mktemp("mapmatch") / "uc200", images=True
    )


def truth_rows(archive: Path) -> list[dict[str, str]]:
    with (archive / "frames.csv").open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def horizontal_errors(estimates: list[Estimate], rows: list[dict[str, str]]) -> np.ndarray:
    """Per capture frame; inf where the method gave no position."""
    out = []
    for est, row in zip(estimates, rows, strict=True):
        if est.enu_m is None:
            out.append(math.inf)
            continue
        out.append(
            math.hypot(est.enu_m[0] - float(row["east_m"]), est.enu_m[1] - float(row["north_m"]))
        )
    return np.array(out)


def run(archive: Path, method: MapMatchLocalizer) -> list[Estimate]:
    with open_archive(archive) as arch:
        context = context_of(arch)
        source = observations(arch, needs_image=method.needs_image)
        return run_method(method, context, source, total=len(arch))


def test_mapmatch_meets_the_urban_200_m_figures(
    flight: Path, mapmatch_on_start: tuple[MapMatchLocalizer, list[Estimate]]
) -> None:
    method, estimates = mapmatch_on_start  # the default method over this flight (conftest)
    errors = horizontal_errors(estimates, truth_rows(flight))
    assert len(errors) > 500
    assert np.all(np.isfinite(errors))  # a position at every frame
    assert float(np.median(errors)) <= 3.0
    assert float(np.mean(errors <= 25.0)) >= 0.98
    # every frame was matched and nearly all accepted, each with a covariance and quality
    assert method.matches_tried == len(errors)
    assert method.matches_accepted >= 0.95 * len(errors)
    fixes = [e for e in estimates if e.quality is not None and e.quality >= 0.5]
    assert len(fixes) == method.matches_accepted
    assert all(e.cov_enu_m2 is not None and 0.5 < e.cov_enu_m2[0] < 50.0 for e in fixes)


def shifted_start(source: Iterator[Observation], east_m: float) -> Iterator[Observation]:
    """The archive's observations with the GNSS fix moved ``east_m`` east (a bad start)."""
    for obs in source:
        g = obs.gnss
        if g is None:
            yield obs
            continue
        lat, lon, _ = ned2geodetic(0.0, east_m, 0.0, g.lat_deg, g.lon_deg, 0.0)
        yield dataclasses.replace(obs, gnss=dataclasses.replace(g, lat_deg=lat, lon_deg=lon))


def test_mapmatch_finds_the_map_again_after_a_bad_start(flight: Path) -> None:
    """Started 60 m off: refused matches widen the search until the frame is found."""
    method = MapMatchLocalizer()
    with open_archive(flight) as arch:
        source = shifted_start(observations(arch, needs_image=False), 60.0)
        estimates = run_method(method, context_of(arch), source, total=len(arch))
    errors = horizontal_errors(estimates, truth_rows(flight))
    assert errors[0] > 50.0
    found = int(np.argmax(errors < 5.0))
    assert 0 < found < 150  # 3 s
    assert float(np.median(errors[found:])) <= 3.0


@pytest.fixture(scope="module")
def driven(flight: Path) -> LocalizeRun:
    """``mapmatch`` through the driver (as ``air-sitl localize`` runs it) against the default
    reference, estimates named ``mm``: read by the tests of the driver and of eval's fixes."""
    return run_archive(flight, "mapmatch", name="mm")


def test_the_driver_writes_mapmatch_estimates(flight: Path, driven: LocalizeRun) -> None:
    """Registered method, the driver's estimates file, one row per frame."""
    result = driven
    assert result.path == flight / "estimates" / "mm.csv"
    with result.path.open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == result.frames == result.estimated_frames


def test_localize_every_k_matches_every_kth_frame(flight: Path) -> None:
    """``air-sitl localize --every 4`` runs ``mapmatch`` with ``every=4``: a match on every
    4th frame only (the propagated position between), a position at every frame."""
    argv = ["localize", str(flight), "--method", "mapmatch", "--every", "4", "--name", "mm4"]
    assert main([*argv, "--quiet"]) == 0
    written = read_rows(flight / "estimates" / "mm4.csv")
    method = MapMatchLocalizer(every=4)
    estimates = run(flight, method)
    assert method.matches_tried == math.ceil(len(estimates) / 4)
    assert len(written) == len(estimates)
    for row, est in zip(written, estimates, strict=True):
        assert est.enu_m is not None
        assert abs(float(row["east_m"]) - est.enu_m[0]) < 1e-3
        assert abs(float(row["north_m"]) - est.enu_m[1]) < 1e-3


def test_truth_pose_rectification_recovers_a_prior_offset(flight: Path) -> None:
    """Geometry check: with the true attitude and height the match lands on the truth
    (the remaining error is the date change and JPEG; date 1's survey misregistration against
    date 0, known, is taken out), whatever the prior's offset."""
    manifest = json.loads((flight / "manifest.json").read_text())
    home = GeoPoint(**manifest["home"])
    reference = open_map("urban", home, seed=0, date=0)
    flown = open_map("urban", home, seed=0, date=1)
    assert isinstance(flown, ProceduralMap)
    matcher = MapMatcher(reference, CameraModel(), home)
    rows = truth_rows(flight)
    errors = []
    gsd = flown.georef.gsd_m
    for k in range(0, len(rows), 60):
        r = rows[k]
        q = (float(r["q_ned_w"]), float(r["q_ned_x"]), float(r["q_ned_y"]), float(r["q_ned_z"]))
        east, north = float(r["east_m"]), float(r["north_m"])
        # Date 1's survey shows the ground that lies (de, dn) away: the match lands there.
        hx, hy = flown.home_px
        de, dn = flown.misregistration_m(hx + east / gsd, hy - north / gsd)
        jpeg = (flight / r["filename"]).read_bytes()
        res = matcher.match(jpeg, q, float(r["alt_rel_m"]), east + 12.0, north - 9.0, 25.0)
        assert res is not None and res.accepted
        assert math.hypot(res.shift_east_m + 12.0 - de, res.shift_north_m - 9.0 - dn) < 1.0
        errors.append(math.hypot(res.east_m - east - de, res.north_m - north - dn))
    assert float(np.median(errors)) < 0.5


@pytest.fixture(scope="module")
def forest_run(flight: Path) -> LocalizeRun:
    """``mapmatch`` through the driver against the forest map (not the flight's), estimates
    named ``mm-forest``: every match should be refused."""
    return run_archive(
        flight, "mapmatch", name="mm-forest", reference_map="forest", reference_date=0
    )


def test_quality_gate_refuses_another_area_and_another_map(
    flight: Path, forest_run: LocalizeRun
) -> None:
    """Frames searched where they are not (400 m off), or against the forest map: refused,
    and the estimate at such a frame is the propagated one with quality 0."""
    manifest = json.loads((flight / "manifest.json").read_text())
    home = GeoPoint(**manifest["home"])
    rows = truth_rows(flight)
    urban = MapMatcher(open_map("urban", home, seed=0, date=0), CameraModel(), home)
    forest = MapMatcher(open_map("forest", home, seed=0, date=0), CameraModel(), home)
    tried = 0
    for k in range(0, len(rows), 40):
        r = rows[k]
        q = (float(r["q_ned_w"]), float(r["q_ned_x"]), float(r["q_ned_y"]), float(r["q_ned_z"]))
        east, north, h = float(r["east_m"]), float(r["north_m"]), float(r["alt_rel_m"])
        jpeg = (flight / r["filename"]).read_bytes()
        for matcher, (pe, pn) in ((urban, (east + 400.0, north)), (forest, (east, north))):
            res = matcher.match(jpeg, q, h, pe, pn, 25.0)
            assert res is not None
            assert not res.accepted, (k, res)
            assert res.quality == 0.0
            tried += 1
    assert tried >= 20

    # Through the method: the forest as reference -> no fix, dead reckoning with quality 0
    # (a fix is an estimate of quality >= 0.5: test_mapmatch_meets_the_urban_200_m_figures).
    estimates = forest_run.estimates
    fixes = [e for e in estimates if e.quality is not None and e.quality >= 0.5]
    assert len(fixes) <= 0.01 * len(estimates)
    assert all(e.quality is not None and e.quality < 0.5 for e in estimates[1:])
    covs = [e.cov_enu_m2[0] for e in estimates if e.cov_enu_m2 is not None]
    assert covs[-1] > covs[1]  # the propagated uncertainty grows


def test_refused_fixes_score_fix_rate_0_with_availability_1(
    flight: Path, driven: LocalizeRun, forest_run: LocalizeRun
) -> None:
    """mapmatch against a map that is not the flight's (the forest under an urban flight):
    every match refused, a propagated position at every frame. eval says both: availability
    1, fix rate 0, no fix for the whole flight; against the right map, fixes nearly always."""
    rows = read_rows(forest_run.path)
    assert {r["fix"] for r in rows} == {"0"}
    refused = evaluate(flight, forest_run.path.stem)
    assert refused["availability"] == 1.0
    assert refused["fix_rate"] == 0.0
    frames = refused["frames"]
    assert refused["longest_without_fix_s"] == pytest.approx(frames * 0.02)
    right = evaluate(flight, driven.path.stem)  # the driver's run against the right map
    assert right["availability"] == 1.0 and right["fix_rate"] >= 0.95
    assert right["longest_without_fix_s"] < 1.0
    vo_like = evaluate(flight, "svo")  # AIR's Svo columns say nothing of fixes
    assert vo_like["fix_rate"] is None and vo_like["longest_without_fix_s"] is None


def test_default_reference_is_another_date(flight: Path) -> None:
    with open_archive(flight) as arch:
        context = context_of(arch)
        assert context.map_date == 1
        reference = open_reference(context)
        assert reference.describe()["date_index"] == 0
        own = open_reference(context_of(arch, reference_date=1))
        assert own.describe()["date_index"] == 1


def test_geotiff_reference(tmp_path_factory: pytest.TempPathFactory) -> None:
    """A GeoTIFF of date 0 (``map make``) as the reference of a flight over date 1."""
    root = tmp_path_factory.mktemp("mapmatch-tif")
    home = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0)
    plan = write_short_plan(root / "UT-200.plan", home, leg_m=60.0, alt_m=200.0)
    tif = root / "urban0.tif"
    origin = f"{home.lat_deg},{home.lon_deg}"
    assert main(["map", "make", "urban", "--out", str(tif), "--size-m", "900", "900",
                 "--origin", origin, "--date", "0"]) == 0  # fmt: skip
    archive = root / "flight"
    argv = ["fly", str(plan), "--air-start", "--map", "urban", "--map-date", "1"]
    assert main([*argv, "--quiet", "--out", str(archive)]) == 0
    result = run_archive(archive, "mapmatch", reference_map=str(tif), reference_date=0)
    with result.path.open(encoding="utf-8", newline="") as f:
        est = list(csv.DictReader(f))
    rows = truth_rows(archive)
    errors = [
        math.hypot(
            float(e["east_m"]) - float(r["east_m"]), float(e["north_m"]) - float(r["north_m"])
        )
        for e, r in zip(est, rows, strict=True)
    ]
    assert len(errors) > 100
    assert float(np.median(errors)) <= 3.0
    assert max(errors) <= 10.0
