"""``fly`` checks that the plan stays on its map, with the camera and with --no-camera alike:
a waypoint off a bounded GeoTIFF map is refused before anything flies, naming the item."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from georef_helpers import HOME, utm_grid, write_tif

from air_sitl.cli import main
from air_sitl.frames import ned2geodetic

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def small_map(tmp_path_factory: pytest.TempPathFactory) -> Path:
    crs, transform, size = utm_grid(HOME, 1.0, 400.0)  # 800 m square around home
    bgr = np.full((size, size, 3), 128, dtype=np.uint8)
    return write_tif(tmp_path_factory.mktemp("map") / "small.tif", bgr, crs, transform)


def _plan(tmp_path: Path, far_m: float) -> Path:
    def item(cmd: int, n: float, e: float, alt: float) -> dict[str, object]:
        lat, lon, _ = ned2geodetic(n, e, 0.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
        return {"type": "SimpleItem", "command": cmd, "frame": 3, "autoContinue": True,
                "params": [0, 0, 0, None, lat, lon, alt]}  # fmt: skip

    doc = {
        "fileType": "Plan", "version": 1, "groundStation": "QGroundControl",
        "mission": {"version": 2, "firmwareType": 12, "vehicleType": 1, "cruiseSpeed": 15,
                    "plannedHomePosition": [HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m],
                    "items": [item(22, 0, 0, 40), item(16, 0, 0, 60), item(16, far_m, 0, 60)]},
    }  # fmt: skip
    path = tmp_path / "bounds.plan"
    path.write_text(json.dumps(doc))
    return path


@pytest.mark.parametrize("camera", [[], ["--no-camera"]], ids=["camera", "no-camera"])
def test_a_waypoint_off_the_map_is_refused(
    tmp_path: Path, small_map: Path, camera: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    plan = _plan(tmp_path, 1500.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--map", str(small_map), "--out", str(out), "--quiet",
                 "--air-start", *camera])  # fmt: skip
    err = capsys.readouterr().err
    assert code != 0
    assert "bounds.plan: item 2" in err and "outside the map" in err, err
    assert not (out / "summary.json").exists()


def test_a_plan_on_the_map_flies_without_camera(tmp_path: Path, small_map: Path) -> None:
    plan = _plan(tmp_path, 300.0)
    out = tmp_path / "out"
    code = main(["fly", str(plan), "--map", str(small_map), "--out", str(out), "--quiet",
                 "--air-start", "--no-camera", "--max-sim-time", "120"])  # fmt: skip
    assert code == 0 and (out / "summary.json").exists()
