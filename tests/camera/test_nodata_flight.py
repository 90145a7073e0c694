"""``fly`` over a GeoTIFF with a nodata stripe says which frames show it, on stderr and in
summary.json's ``frames_with_nodata``; over a fully covered map it says nothing.

Real JSBSim flights (``--air-start``, a 100 m capture leg east at 200 m, about 330 frames) over
rasterio GeoTIFFs written here: a 1 km square at 1 m/px, grey 40..200, with a 10 m wide
black stripe running north-south 150-160 m east of home, tagged nodata (value 0) in one file
and untagged in the other. The frames that really show the stripe are read back from the
archive's JPEGs (black pixels), independently of the renderer's count.
"""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest
from georef_helpers import HOME, latlon_to_px, marks_image, utm_grid, write_tif
from short_plans import write_short_plan

from air_sitl.cli import main

pytestmark = pytest.mark.integration

STRIPE_M = (150.0, 160.0)  # east of home; the capture leg runs east from 0 to 100 m


@pytest.fixture(scope="module")
def maps(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("nodata_flight")
    crs, transform, size = utm_grid(HOME, 1.0, 500.0)
    img, _ = marks_image(size, 1.0, 20.0, 1.5)
    col, _row = latlon_to_px(crs, transform, HOME.lat_deg, HOME.lon_deg)
    c0 = round(col + 0.5 + STRIPE_M[0])
    img[:, c0 : c0 + round(STRIPE_M[1] - STRIPE_M[0])] = 0
    return {
        "tagged": write_tif(folder / "stripe.tif", img, crs, transform, nodata=0),
        "plain": write_tif(folder / "plain.tif", img, crs, transform),
    }


def _fly(tmp_path: Path, tif: Path) -> tuple[dict[str, object], str, Path]:
    plan = write_short_plan(tmp_path / "S-200.plan", HOME, leg_m=100.0, alt_m=200.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--map", str(tif), "--out", str(out), "--quiet",
                 "--air-start", "--nav", "truth", "--render-workers", "1"])  # fmt: skip
    assert code == 0
    return json.loads((out / "summary.json").read_text()), str(out), out


def _dark_shares(out: Path) -> list[float]:
    """Share of black pixels (the stripe; the map is 40..200 elsewhere) of every frame."""
    shares = []
    for jpg in sorted(out.glob("frame_*.jpg")):
        img = cv2.imread(str(jpg))
        assert img is not None
        shares.append(float(np.count_nonzero(img.max(axis=2) < 16)) / (img.shape[0] * img.shape[1]))
    return shares


def test_the_frames_showing_nodata_are_named(
    tmp_path: Path, maps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    summary, _, out = _fly(tmp_path, maps["tagged"])
    err = capsys.readouterr().err
    record = summary["frames_with_nodata"]
    assert isinstance(record, dict)
    dark = _dark_shares(out)
    n = len(dark)
    first_dark = next(i for i, s in enumerate(dark) if s > 0.0)
    assert 0 < first_dark < n - 50  # the stripe comes into view during the leg
    # One run of frames from the stripe's first appearance to the end of the window: the
    # renderer counts a pixel from half nodata on, the black test from nearly all of it (one
    # map pixel is about 3 image rows, 3 frames at 15 m/s).
    [[a, b]] = record["ranges"]
    assert b == n - 1
    assert first_dark - 6 <= a <= first_dark
    assert record["count"] == b - a + 1
    assert record["max_fraction"] == pytest.approx(max(dark), abs=0.01)
    assert 0.04 < record["max_fraction"] < 0.09  # 10 m of the 163 m along the track
    line = f"frames {a}-{b} ({b - a + 1} of {n}) show nodata or ground off the map"
    assert line in err, err
    assert err.count("nodata") == 1


def test_a_fully_covered_flight_says_nothing(
    tmp_path: Path, maps: dict[str, Path], capsys: pytest.CaptureFixture[str]
) -> None:
    summary, _, out = _fly(tmp_path, maps["plain"])
    err = capsys.readouterr().err
    assert "frames_with_nodata" not in summary
    assert "nodata" not in err and "off the map" not in err
    assert max(_dark_shares(out)) > 0.04  # the same black stripe, but it is data here
