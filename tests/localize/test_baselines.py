"""deadreckon and vo on real flights with real frames: offline over an archive, online on the bus.

Error bounds, and why (calm air, the sensor noise of ``manifest.json``):

- deadreckon: the initial fix is off by up to about 5 m (1.5 m per axis, 3 sigma); after it
  the error grows with the AHRS heading error (drift limited to 0.02 rad: up to 2 % of the
  distance flown, across track); airspeed noise (0.3 m/s, white) averages out. Bound:
  5 m + 2 % of the distance.
- vo: the same start and heading error, plus odometry errors of scale (the barometer height:
  0.5 m noise and a random walk on 200 m) and tracking. Bound: 5 m + 5 % of the distance.

Offline, both run over the first 600 frames of UC-200's circle (the session's shared flight,
177 m banked 9 degrees), where they measured: deadreckon max 1.7 m (bound 8.5 m), vo median
0.9 m, max 2.2 m (bound 13.8 m; printed: ``pytest -s``). Over the whole circle (3400 frames,
1020 m) they measured max 2.5 m and 3.6 m against bounds of 25 m and 56 m: the drift is
small, and the short flight's bounds are the tighter ones.
"""

from __future__ import annotations

import csv
import math
import subprocess
import zipfile
from pathlib import Path

import numpy as np
import pytest
from shared_builds import copy_archive
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.dataset.estimates import read_estimates
from air_sitl.dataset.manifest import read_manifest
from air_sitl.files import sha256_file
from air_sitl.localize import localize_archive
from air_sitl.localize.archive import run_archive
from air_sitl.state import GeoPoint
from tests.bus.helpers import cli, fly_with_bus_localizer

pytestmark = pytest.mark.integration

REPO = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


@pytest.fixture(scope="module")
def flight(uc200_date1_start: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The first 600 frames of UC-200 from the air (the session's shared flight, conftest,
    mapmatch's and fused's too): real camera frames over the urban map (its date matters to
    neither method); a copy, which these tests write estimates into."""
    dst = tmp_path_factory.mktemp("localize") / "UC-200"
    return copy_archive(uc200_date1_start, dst, images=True)


def truth_en(archive: Path) -> tuple[np.ndarray, float]:
    with (archive / "frames.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    en = np.array([[float(r["east_m"]), float(r["north_m"])] for r in rows])
    return en, float(np.sum(np.hypot(*np.diff(en, axis=0).T)))


def errors(archive: Path, path: Path) -> tuple[np.ndarray, float]:
    """Horizontal error per frame (every frame must have an estimate) and the distance."""
    en, distance = truth_en(archive)
    points = read_estimates(path, None)
    assert [p.frame for p in points] == list(range(len(en)))
    est = np.array([p.enu_m[:2] for p in points])
    return np.hypot(*(est - en).T), distance


@pytest.mark.parametrize(("method", "drift_fraction"), [("deadreckon", 0.02), ("vo", 0.05)])
def test_offline_estimates_are_within_bounds(
    flight: Path, method: str, drift_fraction: float
) -> None:
    path = localize_archive(flight, method)
    assert path == flight / "estimates" / f"{method}.csv"
    err, distance = errors(flight, path)
    bound = 5.0 + drift_fraction * distance
    print(
        f"\n{method} on UC-200: median {np.median(err):.1f} m, max {err.max():.1f} m, "
        f"final {err[-1]:.1f} m = drift {100 * err[-1] / distance:.2f} % of {distance:.0f} m"
    )
    assert err.max() <= bound, f"max error {err.max():.1f} m > {bound:.1f} m"
    manifest = read_manifest(flight)
    assert manifest is not None
    assert manifest["files"][f"estimates/{method}.csv"] == sha256_file(path)
    assert f"estimates/{method}.csv" in manifest["wall_clock_files"]


def test_same_seed_same_bytes_other_seed_other_bytes(flight: Path) -> None:
    a = run_archive(flight, "deadreckon", name="dr_a", seed=7).path.read_bytes()
    b = run_archive(flight, "deadreckon", name="dr_b", seed=7).path.read_bytes()
    c = run_archive(flight, "deadreckon", name="dr_c", seed=8).path.read_bytes()
    assert a == b
    assert a != c


def test_the_command_writes_a_valid_archive_and_refuses_a_zip(flight: Path, tmp_path: Path) -> None:
    # The command's job (write, manifest, check) is the method's no matter which: the cheap one
    # (VO over the same frames is checked in process above).
    run = subprocess.run(
        cli("localize", str(flight), "--method", "deadreckon", "--name", "dr_cli"),
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert "estimates/dr_cli.csv" in run.stdout
    check = subprocess.run(
        cli("check", str(flight), "--no-images"), capture_output=True, text=True, check=False
    )
    assert check.returncode == 0, check.stdout[-2000:]
    zipped = tmp_path / "uc.zip"  # the archive zipped, but its JPEGs (the refusal needs none)
    with zipfile.ZipFile(zipped, "w") as z:
        for path in sorted(flight.iterdir()):
            if path.is_file() and path.suffix != ".jpg":
                z.write(path, path.name)
    bad = subprocess.run(
        cli("localize", str(zipped), "--method", "vo"),
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert bad.returncode == 2
    lines = bad.stderr.strip().splitlines()
    assert len(lines) == 1 and "zip archive is read-only" in lines[0], bad.stderr
    unknown = subprocess.run(
        cli("localize", str(flight), "--method", "nope"),
        capture_output=True, text=True, timeout=60, check=False,
    )  # fmt: skip
    assert unknown.returncode == 2 and "--method nope" in unknown.stderr


def test_vo_on_the_bus_answers_every_frame_like_offline(tmp_path: Path) -> None:
    """fly --wait-for vo and localize --bus as two processes; then the same offline."""
    plan = write_short_plan(tmp_path / "short.plan", HOME, leg_m=120.0)  # about 360 frames
    out = tmp_path / "bus"
    # The localizer leaves by itself once the capture window is over.
    loc_out = fly_with_bus_localizer(
        ["--method", "vo", "--name", "vo"],
        [str(plan), "--air-start", "--quiet", "--out", str(out), "--zenoh", "--wait-for", "vo"],
    )
    online = out / "estimates" / "vo.csv"
    err, distance = errors(out, online)
    frames = len(err)
    assert frames > 300
    assert f"{frames} frames, {frames} estimated" in loc_out
    assert err.max() <= 5.0 + 0.05 * distance

    # Offline with the inputs the bus carries: the same estimates (CSV rounding aside).
    offline = run_archive(out, "vo", name="vo_offline", bus_inputs=True).path
    a = np.array([p.enu_m for p in read_estimates(online, None)])
    b = np.array([p.enu_m for p in read_estimates(offline, None)])
    assert a.shape == b.shape
    assert np.abs(a - b).max() <= 1e-3
    assert math.isfinite(float(np.abs(a - b).max()))


def test_denial_windows_give_gnss_outside_them_and_deadreckon_learns_the_wind(
    tmp_path: Path,
) -> None:
    """A recorded denial window: fixes before and after it; 4 m/s of wind learnt from them.
    deadreckon reads no pixels: the small camera."""
    plan = write_short_plan(tmp_path / "short.plan", HOME, leg_m=300.0)
    out = tmp_path / "deny"
    run = subprocess.run(
        cli("fly", str(plan), "--air-start", "--quiet", "--out", str(out),
            "--gps-denied-window", "5:12", "--wind", "4@270", *SMALL_CAMERA),
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    from air_sitl.dataset.reader import open_archive
    from air_sitl.localize.archive import observations

    with open_archive(out) as archive:
        given = [
            (o.frame, o.sim_time_ns, o.gnss.sim_time_ns)
            for o in observations(archive, needs_image=False)
            if o.gnss is not None
        ]
    assert given[0][0] == 0
    assert all(not (5e9 <= t < 12e9 or 5e9 <= fix_t < 12e9) for _k, t, fix_t in given)
    assert any(t >= 12e9 for _k, t, _f in given)  # fixes again after the window
    err, _distance = errors(out, localize_archive(out, "deadreckon"))
    with (out / "frames.csv").open(newline="") as f:
        t = np.array([int(r["sim_time_ns"]) for r in csv.DictReader(f)])
    inside = (t >= 5e9) & (t < 12e9)
    # 7 s without GNSS: an unknown 4 m/s wind alone would make 28 m
    assert err[inside].max() <= 5.0, err[inside].max()
