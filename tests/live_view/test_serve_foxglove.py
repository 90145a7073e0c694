"""``serve --foxglove 127.0.0.1:0``: a served vehicle on the ground seen by a client written from
the protocol's spec: truth fixes at home, the preloaded mission, the STATUSTEXT it sends."""

from __future__ import annotations

import re
import tempfile
from pathlib import Path

import pytest
import short_plans
from mavlink.gcs import Gcs, serve

from .ws_client import FoxgloveClient

pytestmark = pytest.mark.integration

V = "/air/uav0/"


def test_serve_streams_the_vehicle_and_its_statustext(tmp_path: Path) -> None:
    from air_sitl.state import GeoPoint

    home = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
    plan = short_plans.write_short_plan(tmp_path / "p.plan", home, leg_m=30.0)
    with (
        tempfile.TemporaryFile("w+") as err,
        serve(
            "--mavlink",
            "udpin:127.0.0.1:0",
            "--plan",
            str(plan),
            "--foxglove-image-hz",
            "0",
            "--foxglove",
            "127.0.0.1:0",
            stderr=err,
        ) as served,
    ):
        err.seek(0)
        port = int(re.search(r"foxglove: ws://127\.0\.0\.1:(\d+) \(uav0\)", err.read()).group(1))  # type: ignore[union-attr]
        client = FoxgloveClient("127.0.0.1", port)
        while not {V + "truth/fix", V + "mission", V + "log"} <= client.topics():
            client.recv()
        client.subscribe([V + "truth/fix", V + "mission", V + "log"])
        got: dict[str, list[object]] = {}
        while not {V + "truth/fix", V + "mission"} <= set(got):
            item = client.recv()
            if item[0] == "message":
                got.setdefault(item[1], []).append(item[3])
        fix = got[V + "truth/fix"][0]
        assert abs(fix.latitude - home.lat_deg) < 1e-4  # type: ignore[attr-defined]
        assert abs(fix.longitude - home.lon_deg) < 1e-4  # type: ignore[attr-defined]
        gcs = Gcs(f"udpout:127.0.0.1:{served.ports[0]}")
        try:
            gcs.connect()
            gcs.set_param("NAV_LOITER_RAD", float("nan"))  # refused with a STATUSTEXT
            text = gcs.wait_whole_text("NAV_LOITER_RAD: value nan")
        finally:
            gcs.close()
        texts: list[str] = []  # the vehicle's STATUSTEXT on the log topic, in order
        while text not in texts:
            item = client.recv()
            if item[0] == "message" and item[1] == V + "log" and item[3].name == "vehicle":  # type: ignore[attr-defined]
                texts.append(item[3].message)  # type: ignore[attr-defined]
        client.close()
