"""``fly --foxglove 127.0.0.1:0 --foxglove-mcap FILE``: a real short flight (JSBSim, camera,
onboard EKF) with a localizer answering every frame over the zenoh bus serves the view and
records the same topics; the recording is checked against the archive and the estimates."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import short_plans
from bus.helpers import fly_with_bus_localizer
from cli_errors import one_line_error
from mcap.reader import make_reader

import air_sitl.dataset
from air_sitl.state import GeoPoint

from .decode import Decoder

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
V = "/air/uav0/"


def test_fly_serves_and_records_the_flight_and_the_bus_estimates(tmp_path: Path) -> None:
    plan = short_plans.write_short_plan(tmp_path / "p.plan", HOME, leg_m=30.0)
    out, rec = tmp_path / "out", tmp_path / "live.mcap"
    fly_with_bus_localizer(
        ["--method", "vo", "--name", "vo"],
        [str(plan), "--air-start", "--quiet", "--out", str(out), "--zenoh", "--wait-for", "vo",
         "--foxglove", "127.0.0.1:0", "--foxglove-mcap", str(rec)],
    )  # fmt: skip
    decoder = Decoder()
    got: dict[str, list[tuple[int, object]]] = {}
    with rec.open("rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(log_time_order=False):
            assert schema is not None
            decoder.add(schema.name, schema.encoding, schema.data)
            value = decoder.decode(schema.name, channel.message_encoding, message.data)
            got.setdefault(channel.topic, []).append((message.log_time, value))
    with air_sitl.dataset.open(out) as archive:
        jpeg_at = {archive.timestamp_ns(k): archive.jpeg(k) for k in range(len(archive))}
    images = got[V + "camera/image"]
    # 10 of the camera's 50 frames a second; each the archive's frame of that time.
    assert abs(len(images) - len(jpeg_at) / 5) <= 2
    for t, img in images:
        assert img.data == jpeg_at[t]  # type: ignore[attr-defined]
    trajectory = {int(r["sim_time_ns"]): r for r in csv.DictReader((out / "trajectory.csv").open())}
    fixes = got[V + "truth/fix"]
    assert len(fixes) > 10
    checked = 0
    for t, fix in fixes:
        if t in trajectory:
            assert abs(fix.latitude - float(trajectory[t]["lat_deg"])) < 1e-8  # type: ignore[attr-defined]
            checked += 1
    assert checked
    doc = json.loads(got[V + "mission"][0][1].geojson)  # type: ignore[attr-defined]
    assert any(f["properties"]["name"] == "route" for f in doc["features"])
    assert got[V + "gnss/fix"] and got[V + "log"]
    # The onboard filter and the estimates the bus brought, each its own topic.
    assert got[V + "nav/fix"] and got[V + "nav/pose"]
    rows = list(csv.DictReader((out / "estimates" / "vo.csv").open()))
    poses = {t: p for t, p in got[V + "estimates/vo/pose"]}
    assert len(got[V + "estimates/vo/fix"]) >= len(rows) > 50
    for r in rows:
        p = poses[int(r["sim_time_ns"])].pose.position  # type: ignore[attr-defined]
        assert abs(p.x - float(r["east_m"])) < 1e-3 and abs(p.y - float(r["north_m"])) < 1e-3
    sources = {e["source"] for _, e in got[V + "errors"]}  # type: ignore[index]
    assert sources == {"nav", "estimates/vo"}


def test_a_bad_endpoint_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    plan = short_plans.write_short_plan(tmp_path / "p.plan", HOME, leg_m=30.0)
    args = ["fly", str(plan), "--out", str(tmp_path / "o"), "--foxglove", "localhost:http"]
    line = one_line_error(args, capsys)
    assert "--foxglove: 'localhost:http' is not [HOST:]PORT" in line
    assert not (tmp_path / "o").exists()
