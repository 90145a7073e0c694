"""README's tour runs as written, in order, in a fresh folder.

The tour's lines are the Getting started page's, in the same order: tests/docs/test_doc_blocks.py
runs that page's blocks (with every other page's) in one fresh folder and checks what they write,
so the tour is run there, on short versions of AIR's plans (the flights take seconds, not
minutes; see that module). What short plans cannot show is tested here on the full plan: the
tour's GeoTIFF window covers UC-200 as it flies, so its flight over the maps shows no nodata or
ground off the map.
"""

from __future__ import annotations

import csv
import re
import shlex
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rasterio.warp import transform as warp_transform

from air_sitl.camera.model import CameraModel
from air_sitl.frames import ned2geodetic

REPO = Path(__file__).resolve().parents[2]


def commands(text: str) -> list[str]:
    """The command lines of every ``sh`` block of a page, comments and blank lines left out."""
    found = []
    for body in re.findall(r"^```sh\n(.*?)^```", text, re.S | re.M):
        for line in re.sub(r"\\\n\s*", "", body).splitlines():
            argv = shlex.split(line, comments=True)
            if argv:
                found.append(shlex.join(argv))
    return found


def tour_lines() -> list[str]:
    """The command lines of README's tour, comments included."""
    text = (REPO / "README.md").read_text(encoding="utf-8")
    after = text.split("\n## A tour\n", 1)[1]
    block = after.split("```sh\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


def test_the_tour_has_10_to_15_lines_each_a_command() -> None:
    lines = tour_lines()
    assert 10 <= len(lines) <= 15, lines
    assert all(line.startswith("air-sitl ") for line in lines), lines
    assert all(len(line) < 200 for line in lines)
    assert not any("PLAN" in line for line in lines)  # no placeholder to fill in


def test_the_tour_is_getting_started_in_the_same_order() -> None:
    """So the docs-blocks runner, which runs Getting started, runs the tour as written."""
    tour = [shlex.join(shlex.split(line, comments=True)) for line in tour_lines()]
    page = commands((REPO / "docs" / "getting-started.md").read_text(encoding="utf-8"))
    in_page = [line for line in page if line in tour]
    assert in_page == tour, "README's tour lines missing from docs/getting-started.md or reordered"


def _map_window_lines() -> tuple[list[str], str]:
    """The tour's ``map make`` lines and the plan its GeoTIFF flight flies."""
    lines = [shlex.split(ln, comments=True) for ln in tour_lines()]
    makes = [argv for argv in lines if argv[1:3] == ["map", "make"]]
    flight = next(argv for argv in lines if argv[1] == "fly" and "--map" in argv)
    maps = flight[flight.index("--map") + 1].split(",")
    assert [argv[argv.index("--out") + 1] for argv in makes] == maps
    return makes[0], flight[2]


@pytest.mark.integration
def test_the_tour_map_window_covers_uc200_as_it_flies(tmp_path: Path) -> None:
    """Every capture frame's ground footprint of the full plan (flown without the camera: the
    same trajectory) lies inside the window the tour's ``map make`` lines write (a flat ground
    at the runway's height: the town's relief only narrows the footprints)."""
    make, plan = _map_window_lines()
    # map make centres a --size-m window on --origin in the origin's UTM zone (north).
    lat0, lon0 = (float(v) for v in make[make.index("--origin") + 1].split(","))
    w_m, h_m = (float(v) for v in make[make.index("--size-m") + 1 :][:2])
    crs = f"EPSG:{32600 + int((lon0 + 180.0) // 6.0) + 1}"
    (x0,), (y0,) = warp_transform("EPSG:4326", crs, [lon0], [lat0])
    air = [sys.executable, "-m", "air_sitl"]
    out = tmp_path / "flight"
    fly = [*air, "fly", plan, "--no-camera", "--quiet", "--out", str(out)]
    subprocess.run(fly, check=True, capture_output=True, cwd=REPO)

    rows = list(csv.DictReader((out / "trajectory.csv").open()))
    capture = [r for r in rows if r["capturing"] == "1"]
    assert len(capture) > 1000, len(capture)
    camera = CameraModel()
    k_inv = np.linalg.inv(camera.intrinsics())
    w, h = camera.width_px - 1, camera.height_px - 1
    home = rows[0]
    ground_m = float(home["alt_amsl_m"]) + float(home["down_m"])  # the runway's height
    lons, lats = [], []
    for r in capture:
        q = tuple(float(r[k]) for k in ("qw", "qx", "qy", "qz"))
        rot = camera.r_cam_to_ned(q)  # type: ignore[arg-type]
        north, east = float(r["north_m"]), float(r["east_m"])
        height_m = float(r["alt_amsl_m"]) - ground_m
        for u, v in ((0, 0), (w, 0), (w, h), (0, h)):
            ray = rot @ (k_inv @ np.array([u, v, 1.0]))
            s = height_m / ray[2]
            lat, lon, _ = ned2geodetic(
                north + s * ray[0], east + s * ray[1], 0.0,
                float(home["lat_deg"]), float(home["lon_deg"]), 0.0,
            )  # fmt: skip
            lons.append(lon)
            lats.append(lat)
    xs, ys = warp_transform("EPSG:4326", crs, lons, lats)
    left, right, bottom, top = x0 - w_m / 2, x0 + w_m / 2, y0 - h_m / 2, y0 + h_m / 2
    outside = [
        (x, y) for x, y in zip(xs, ys, strict=True)
        if not (left <= x <= right and bottom <= y <= top)
    ]  # fmt: skip
    assert not outside, f"{len(outside)} footprint corners off the tour's map, e.g. {outside[:3]}"
