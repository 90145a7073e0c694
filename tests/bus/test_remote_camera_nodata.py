"""``fly --camera remote`` over a GeoTIFF with a nodata stripe warns and records the frames that
show it exactly as the in-process camera does: the bridge's reply carries each frame's
``nodata_fraction``.

The map of ``tests/camera/test_nodata_flight.py`` (a 1 km square at 1 m/px, a 10 m nodata
stripe 150-160 m east of home) under the same short flight (air start, a 100 m capture leg
east at 200 m, about 330 frames), flown by two ``air-sitl fly`` processes: one rendering
itself, one asking ``air-sitl camera-bridge --map stripe.tif`` for every frame.
"""

from __future__ import annotations

import json
import signal
import subprocess
from pathlib import Path

import pytest
from georef_helpers import latlon_to_px, marks_image, utm_grid, write_tif
from short_plans import write_short_plan

from .helpers import HOME, WAIT_SAFETY, cli, free_endpoint, start, stop, wait_for_line

pytestmark = pytest.mark.integration

STRIPE_M = (150.0, 160.0)  # east of home; the capture leg runs east from 0 to 100 m


def _stripe_map(folder: Path) -> Path:
    crs, transform, size = utm_grid(HOME, 1.0, 500.0)
    img, _ = marks_image(size, 1.0, 20.0, 1.5)
    col, _row = latlon_to_px(crs, transform, HOME.lat_deg, HOME.lon_deg)
    c0 = round(col + 0.5 + STRIPE_M[0])
    img[:, c0 : c0 + round(STRIPE_M[1] - STRIPE_M[0])] = 0
    return write_tif(folder / "stripe.tif", img, crs, transform, nodata=0)


def _fly(plan: Path, tif: Path, out: Path, *extra: str) -> tuple[dict[str, object], list[str]]:
    """(summary.json, the stderr lines about nodata) of one flight."""
    run = subprocess.run(
        cli("fly", str(plan), "--map", str(tif), "--out", str(out), "--quiet", "--air-start",
            "--nav", "truth", *extra),
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    lines = [ln for ln in run.stderr.splitlines() if "nodata" in ln]
    return json.loads((out / "summary.json").read_text()), lines


def test_a_remote_camera_flight_warns_and_records_nodata_as_a_local_one(tmp_path: Path) -> None:
    tif = _stripe_map(tmp_path)
    plan = write_short_plan(tmp_path / "S-200.plan", HOME, leg_m=100.0, alt_m=200.0)
    local, local_lines = _fly(plan, tif, tmp_path / "local", "--render-workers", "1")
    record = local["frames_with_nodata"]
    assert isinstance(record, dict) and record["count"] > 10, record
    assert len(local_lines) == 1 and "show nodata or ground off the map" in local_lines[0]

    endpoint = free_endpoint()
    bridge = start(cli("camera-bridge", "--map", str(tif), "--zenoh-connect", endpoint))
    try:
        wait_for_line(bridge, "serving")
        remote, remote_lines = _fly(
            plan, tif, tmp_path / "remote",
            "--camera", "remote", "--zenoh-listen", endpoint, *WAIT_SAFETY,
        )  # fmt: skip
    finally:
        code, _, err = stop(bridge, signal.SIGTERM)
    assert code == 0, err
    assert remote.get("frames_with_nodata") == record
    assert remote_lines == local_lines
    a, b = tmp_path / "local", tmp_path / "remote"
    assert (a / "metadata.csv").read_bytes() == (b / "metadata.csv").read_bytes()
    assert (a / "frames.csv").read_bytes() == (b / "frames.csv").read_bytes()
