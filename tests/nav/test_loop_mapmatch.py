"""The real online map-matcher as the aid, in lockstep, twice: the same bytes.

``fly --nav-aid mm --wait-for mm`` and ``localize --bus --method mapmatch`` as two processes,
GNSS denied after a few seconds so that the filter flies on the map-matcher. Its answers
depend only on the frames and sensors it is given (at their simulated times), so two flights
write the same trajectory, frames and estimates. (Before, ``cv2.magnitude`` rounded with the
alignment of its buffer, and the runs parted at the first accepted match.)
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
from short_plans import write_short_plan

from tests.bus.helpers import HOME, fly_with_bus_localizer

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def plan(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_short_plan(
        tmp_path_factory.mktemp("plan") / "MM.plan", HOME, leg_m=100.0, alt_m=120.0
    )


def aided_by_mapmatch(plan: Path, out: Path) -> str:
    """Fly ``plan`` into ``out`` aided by the online map-matcher; its closing line."""
    return fly_with_bus_localizer(
        ["--method", "mapmatch", "--name", "mm", "--gnss", "all", "--reference-map", "urban"],
        [str(plan), "--air-start", "--quiet", "--out", str(out), "--gps-denied-after", "2",
         "--wind", "5@270", "--nav-aid", "mm", "--wait-for", "mm"],
    )  # fmt: skip


def test_the_online_mapmatcher_as_a_lockstep_aid_is_deterministic(
    plan: Path, tmp_path: Path
) -> None:
    a, b = tmp_path / "a", tmp_path / "b"
    said = aided_by_mapmatch(plan, a)
    aided_by_mapmatch(plan, b)
    nav = json.loads((a / "summary.json").read_text())["nav"]
    # The map-matcher is what the filter flies on while GNSS is denied.
    assert nav["gnss_denied_s"] > 4.0, nav
    assert nav["aid"]["fused"] > 200, nav["aid"]
    assert "frames" in said
    for name in ("trajectory.csv", "frames.csv", "metadata.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    assert simulated(a / "estimates/mm.csv") == simulated(b / "estimates/mm.csv")
    # Wall-clock figures: frames_reoffered counts frames put again after a wall-clock wait
    # for their answer (a loaded machine makes some), the bytes above are the same anyway.
    strip = ("wall_time_s", "realtime_factor", "lockstep_wait_wall_s", "plan", "frames_reoffered")
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    assert {k: v for k, v in sa.items() if k not in strip} == {
        k: v for k, v in sb.items() if k not in strip
    }


def simulated(log: Path) -> list[list[str]]:
    """An estimate log without its wall-clock column (``latency_wall_ms``)."""
    with log.open(newline="") as f:
        rows = list(csv.reader(f))
    drop = rows[0].index("latency_wall_ms")
    assert len(rows) > 100
    return [r[:drop] + r[drop + 1 :] for r in rows]
