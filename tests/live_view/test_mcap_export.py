"""``export ARCHIVE --mcap FILE`` read back with the ``mcap`` package and protobuf alone."""

from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest
from mcap.reader import make_reader

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.manifest import refresh_manifest
from air_sitl.dataset.writer import DatasetWriter
from air_sitl.mission.plan_file import plan_text, read_plan
from tests.dataset.synth import HOME, fly
from tests.dataset.test_writer import _info

from .decode import Decoder

FRAMES = 20
ROOT = Path(__file__).resolve().parents[2]
MISSIONS = ROOT / "missions"
V = "/air/uav0/"


@pytest.fixture(scope="module")
def archive_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("fox") / "a"
    info = _info()
    plan = plan_text(read_plan(MISSIONS / "FL-200.plan"))
    info = dataclasses.replace(info, plan_text=plan)
    writer = DatasetWriter(folder, info)
    fly(writer, FRAMES)
    writer.finish({"capture_distance_m": 1.0})
    with air_sitl.dataset.open(folder) as archive:
        times = [archive.timestamp_ns(k) for k in range(len(archive))]
        enu = [archive.rows[k].pose_enu_m for k in range(len(archive))]
    est = folder / "estimates"
    est.mkdir(exist_ok=True)
    lines = ["sim_time_ns,east_m,north_m,up_m"]
    for k in range(0, FRAMES, 2):  # 3 m east of the truth, every other frame
        lines.append(f"{times[k]},{enu[k][0] + 3.0:.4f},{enu[k][1]:.4f},{enu[k][2]:.4f}")
    (est / "vpr.csv").write_text("\n".join(lines) + "\n")
    refresh_manifest(folder)
    return folder


def _read(path: Path) -> tuple[dict[str, list[tuple[int, Any]]], dict[str, str]]:
    decoder = Decoder()
    out: dict[str, list[tuple[int, Any]]] = {}
    schemas: dict[str, str] = {}
    with path.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            assert schema is not None
            decoder.add(schema.name, schema.encoding, schema.data)
            schemas[channel.topic] = schema.name
            value = decoder.decode(schema.name, channel.message_encoding, message.data)
            out.setdefault(channel.topic, []).append((message.log_time, value))
    return out, schemas


def test_mcap_has_the_archive_frames_fixes_and_estimates(archive_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "flight.mcap"
    assert main(["export", str(archive_dir), "--mcap", str(out)]) == 0
    topics, schemas = _read(out)
    assert schemas[V + "camera/image"] == "foxglove.CompressedImage"
    assert schemas[V + "camera/calibration"] == "foxglove.CameraCalibration"
    assert schemas[V + "truth/fix"] == "foxglove.LocationFix"
    assert schemas[V + "estimates/vpr/fix"] == "foxglove.LocationFix"
    assert schemas[V + "estimates/vpr/pose"] == "foxglove.PoseInFrame"
    assert schemas["/tf"] == "foxglove.FrameTransforms"
    assert schemas[V + "mission"] == schemas[V + "camera/footprint"] == "foxglove.GeoJSON"
    assert schemas[V + "log"] == "foxglove.Log"
    assert schemas[V + "gnss/fix"] == "foxglove.LocationFix"
    frames_csv = list(csv.DictReader((archive_dir / "frames.csv").open()))
    with air_sitl.dataset.open(archive_dir) as archive:
        images = topics[V + "camera/image"]
        fixes = topics[V + "truth/fix"]
        assert len(images) == len(fixes) == len(topics["/tf"]) == FRAMES
        for k, ((t_img, img), (t_fix, fix)) in enumerate(zip(images, fixes, strict=True)):
            t = archive.timestamp_ns(k)
            assert t_img == t_fix == t
            assert img.timestamp.seconds * 10**9 + img.timestamp.nanos == t
            assert img.data == archive.jpeg(k) and img.format == "jpeg"
            assert img.frame_id == "camera_optical_frame"
            row = frames_csv[k]
            assert fix.latitude == float(row["lat_deg"])
            assert fix.longitude == float(row["lon_deg"])
            assert fix.altitude == float(row["alt_amsl_m"])
        for _, tf in topics["/tf"]:
            frames = [(x.parent_frame_id, x.child_frame_id) for x in tf.transforms]
            assert frames == [("map", "base_link"), ("base_link", "camera_optical_frame")]
            for x in tf.transforms:
                r = x.rotation
                assert math.isclose(math.hypot(r.x, r.y, r.z, r.w), 1.0, abs_tol=1e-9)
        _, pose0 = topics[V + "truth/pose"][0]
        p = pose0.pose.position
        assert (p.x, p.y, p.z) == archive.rows[0].pose_enu_m
        assert pose0.frame_id == "map"
        cal = topics[V + "camera/calibration"][0][1]
        assert (cal.width, cal.height) == (160, 120)
    est_fix = topics[V + "estimates/vpr/fix"]
    assert len(est_fix) == len(topics[V + "estimates/vpr/pose"]) == FRAMES // 2
    errs = [e for _, e in topics[V + "errors"] if e["source"] == "estimates/vpr"]
    assert len(errs) == FRAMES // 2
    assert all(abs(e["horizontal_m"] - 3.0) < 1e-3 and e["vertical_m"] < 1e-3 for e in errs)
    mission = json.loads(topics[V + "mission"][0][1].geojson)
    names = [f["properties"]["name"] for f in mission["features"]]
    assert "route" in names and any(n.startswith("WP ") for n in names)
    footprint = json.loads(topics[V + "camera/footprint"][0][1].geojson)
    ring = footprint["features"][0]["geometry"]["coordinates"][0]
    lon, lat = ring[0]
    assert len(ring) == 5 and abs(lat - HOME.lat_deg) < 0.05 and abs(lon - HOME.lon_deg) < 0.05
    _layout_names_these_topics(set(topics))


def _strings(value: Any) -> list[str]:
    if isinstance(value, dict):
        return [*value.keys(), *(s for v in value.values() for s in _strings(v))]
    if isinstance(value, list):
        return [s for v in value for s in _strings(v)]
    return [value] if isinstance(value, str) else []


def _layout_names_these_topics(topics: set[str]) -> None:
    """docs/foxglove/air-sitl-layout.json: every topic it names is one the export wrote (a
    message path's filter and field cut off), every panel of its mosaic is configured."""
    layout = json.loads((ROOT / "docs" / "foxglove" / "air-sitl-layout.json").read_text())
    named = {s.split("{")[0].split(".")[0] for s in _strings(layout) if s.startswith("/air/")}
    # The scripted flight has no onboard filter (--nav ekf): its topics are the live view's.
    nav = {V + "nav/fix", V + "nav/pose"}
    assert named and named <= topics | nav, named - topics - nav
    panels = [s for s in _strings(layout["layout"]) if "!" in s]
    assert len(panels) == len(layout["configById"]) and set(panels) == set(layout["configById"])


def test_mcap_refuses_to_overwrite(archive_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "exists.mcap"
    out.write_bytes(b"keep")
    assert main(["export", str(archive_dir), "--mcap", str(out)]) == 2
    assert out.read_bytes() == b"keep"
    assert main(["export", str(archive_dir), "--mcap", str(out), "--overwrite"]) == 0
    assert out.read_bytes()[:8] == b"\x89MCAP0\r\n"  # replaced by a recording


def test_without_the_sdk_one_line_names_the_install(tmp_path: Path) -> None:
    """A ``foxglove`` that cannot be imported (as where the extra is not installed)."""
    fake = tmp_path / "site" / "foxglove"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('No module named foxglove')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(fake.parent), str(ROOT)]))
    out = tmp_path / "x.mcap"
    for argv in (
        ["export", str(tmp_path), "--mcap", str(out)],
        ["fly", str(MISSIONS / "FL-200.plan"), "--out", str(tmp_path / "o"), "--foxglove"],
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "air_sitl", *argv],
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp_path,
            check=False,
        )
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.count("\n") == 1, proc.stderr
        assert "pip install 'air-sitl[foxglove]'" in proc.stderr
    assert not out.exists() and not (tmp_path / "o").exists()
