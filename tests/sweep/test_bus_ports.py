"""The bus ports of sweep and bench flights: a port taken between being picked and the flight
listening on it costs a retry on another port, not the run; a sweep run on the bus listens on
a port the system picks as it binds."""

from __future__ import annotations

import contextlib
import json
import socket
import sys
import threading
from collections.abc import Iterator
from pathlib import Path

import ports
import pytest
import short_plans
import yaml

from air_sitl.localize import external
from air_sitl.localize.external import ExternalLocalizer, fly_in_lockstep
from air_sitl.state import GeoPoint
from air_sitl.sweep import load_spec, make_tasks
from air_sitl.sweep.run import execute

pytestmark = pytest.mark.integration

ROOT = Path(__file__).resolve().parents[2]
HOME = GeoPoint(lat_deg=38.54, lon_deg=-121.49, alt_amsl_m=10.0)


@contextlib.contextmanager
def hanging_up(listener: socket.socket) -> Iterator[None]:
    """Accept and close each connection to ``listener`` until the block ends."""
    done = threading.Event()

    def run() -> None:
        listener.settimeout(0.1)
        while not done.is_set():
            with contextlib.suppress(TimeoutError):
                listener.accept()[0].close()

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()
        thread.join()


def test_a_port_taken_before_the_flight_listens_is_replaced(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    plan = short_plans.write_short_plan(tmp_path / "UT-200.plan", HOME, leg_m=30.0)
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        # The race: the first port picked is listened on by another program by the time the
        # flight binds it (the picks after it are this test worker's free ports).
        holder.bind(("127.0.0.1", ports.free_port()))
        holder.listen()
        taken = int(holder.getsockname()[1])
        picks: Iterator[int] = iter([taken])
        monkeypatch.setattr(external, "free_port", lambda: next(picks, None) or ports.free_port())
        localizer = ExternalLocalizer(
            name="ex",
            argv=(sys.executable, str(ROOT / "bridges" / "example_localizer.py"), "--name", "ex"),
        )
        log = tmp_path / "ex.log"
        # The holder hangs up on whoever connects (the localizer): a program that accepted and
        # said nothing would hold the localizer's zenoh handshake, and its SIGINT, for 10 s.
        with hanging_up(holder):
            why = fly_in_lockstep(
                plan,
                ["--air-start", "--nav", "truth", "--wait-timeout", "120"],
                tmp_path / "flight",
                localizer,
                log,
            )
        assert next(picks, None) is None  # the taken port was handed out
    assert why is None, why
    assert f"tcp/127.0.0.1:{taken} was taken; again on another port" in log.read_text()
    summary = json.loads((tmp_path / "flight" / "summary.json").read_text())
    assert summary["mission_completed"] and summary["estimates"]["ex"] == summary["frames_written"]


def test_a_sweep_run_on_the_bus_listens_where_the_system_says(tmp_path: Path) -> None:
    short_plans.write_short_plan(tmp_path / "UT-200.plan", HOME, leg_m=30.0)
    spec_path = tmp_path / "bus.yaml"
    content = {"base": {"plan": "UT-200.plan", "air-start": True, "zenoh": True, "seed": 1}}
    spec_path.write_text(yaml.safe_dump(content), encoding="utf-8")
    (task,) = make_tasks(load_spec(spec_path), tmp_path / "sweep")
    row = execute(task)
    assert row["error"] is None, row["error"]
    assert row["summary"]["frames_published"] == row["summary"]["frames_written"] > 50
