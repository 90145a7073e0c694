"""The router killed mid-flight and restarted on the same port 4 s later (real processes,
client mode: every sample goes through the router). In lockstep the awaited frame is offered
again once the bus is back and the flight goes on, every frame answered; without lockstep the
frames that got no estimate are counted in summary.json and told at the exit."""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path

import pytest
from short_plans import SMALL_CAMERA, write_short_plan

from air_sitl.bus.lockstep import REOFFER_S

from .helpers import HOME, cli, free_endpoint, start, stop, wait_for_line, wait_until

pytestmark = pytest.mark.integration

# The scenario: how long the router stays away (not a speed assumption). Twice the lockstep's
# re-offer period: the awaited frame is offered again at least once while the bus is down.
OUTAGE_S = 2 * REOFFER_S


def rows(path: Path) -> int:
    try:
        return max(0, len(path.read_text().splitlines()) - 1)
    except OSError:
        return 0


@pytest.mark.parametrize("lockstep", [True, False])
def test_a_router_restarted_mid_flight(tmp_path: Path, lockstep: bool) -> None:
    plan = write_short_plan(tmp_path / "UB.plan", HOME, leg_m=250.0)
    endpoint = free_endpoint()
    net = ["--zenoh-connect", endpoint, "--zenoh-mode", "client"]
    router = start(cli("router", "--listen", endpoint))
    wait_for_line(router, "listening on")
    loc = start(cli("localize", "--bus", "--method", "deadreckon", "--name", "dr",
                    "--wait", "120", *net))  # fmt: skip
    out = tmp_path / "out"
    mode = ["--wait-for", "dr", "--wait-timeout", "120"] if lockstep else ["--svo-columns", "dr"]
    # Paced at 4x (a lockstep flight waits for the localizer anyway): the outage falls inside
    # the capture leg.
    fly = start(cli("fly", str(plan), "--air-start", "--quiet", "--out", str(out),
                    "--speed", "4", *mode, *net, *SMALL_CAMERA))  # fmt: skip
    try:
        assert wait_until(lambda: rows(out / "estimates" / "dr.csv") >= 50), "no estimates"
        router.send_signal(signal.SIGKILL)
        router.communicate()
        time.sleep(OUTAGE_S)
        router = start(cli("router", "--listen", endpoint))
        wait_for_line(router, "listening on")
        _, fly_err = fly.communicate(timeout=600)
    finally:
        for proc in (fly, loc, router):
            stop(proc)
    assert fly.returncode == 0, fly_err
    summary = json.loads((out / "summary.json").read_text())
    published = summary["frames_published"]
    answered = summary["estimates"]["dr"]
    assert published == summary["capture_frames"] > 500
    assert summary["frames_without_estimate"] == {"dr": published - answered}
    if lockstep:
        assert answered == published  # every frame answered: the flight went on
        assert summary["frames_reoffered"] >= 1
        assert "got no estimate" not in fly_err
    else:
        assert answered < published  # the outage cost frames, and says so
        assert f"{published - answered} of {published} frames got no estimate from 'dr'" in (
            fly_err
        )
