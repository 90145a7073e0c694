"""``air-sitl check`` tells a recording stopped by Ctrl-C (exit 3, INCOMPLETE) from a complete
one (0, VALID) and a corrupted one (1, INVALID): a real ``fly`` interrupted by SIGINT."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from short_plans import write_short_plan

from air_sitl.cli import main
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration

HOME = GeoPoint(lat_deg=47.3769, lon_deg=8.5417, alt_amsl_m=400.0)


def check(archive: Path, capsys: pytest.CaptureFixture[str], *extra: str) -> tuple[int, str]:
    """``air-sitl check``'s exit code and its report (stdout)."""
    capsys.readouterr()
    code = main(["check", str(archive), *extra])
    return code, capsys.readouterr().out


def test_interrupted_complete_and_corrupted_recordings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    plan = write_short_plan(tmp_path / "UC-200.plan", HOME, leg_m=60.0)  # about 200 frames
    out = tmp_path / "rec"
    fly = ["fly", str(plan), "--out", str(out), "--air-start", "--quiet"]
    proc = subprocess.Popen(
        [sys.executable, "-m", "air_sitl", *fly],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        # A terminal's Ctrl-C finds SIGINT at its default (a background job would ignore it).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # noqa: PLW1509
    )
    metadata = out / "metadata.csv"
    interrupted = False
    while proc.poll() is None:  # an event of the flight: rows on disk, not a delay
        with contextlib.suppress(OSError):
            if metadata.read_bytes().count(b"\n") > 20:
                proc.send_signal(signal.SIGINT)
                interrupted = True
                break
        time.sleep(0.005)
    assert proc.wait(timeout=120) != 0 and interrupted
    assert proc.stderr is not None
    proc.stderr.close()

    code, report = check(out, capsys)
    verdict = report.strip().splitlines()[-1]
    assert code == 3, report
    assert verdict.startswith("INCOMPLETE: valid so far") and "--resume" in verdict, verdict

    assert main([*fly, "--resume"]) == 0
    code, report = check(out, capsys)
    assert code == 0 and report.strip().splitlines()[-1] == "VALID", report

    frame = out / "frame_000010.jpg"
    data = bytearray(frame.read_bytes())
    data[len(data) // 2] ^= 0xFF  # one byte of one image: its SHA-256 no longer matches
    frame.write_bytes(bytes(data))
    code, report = check(out, capsys, "--no-images")
    assert code == 1 and report.strip().splitlines()[-1].startswith("INVALID ("), report
    assert "frame_000010.jpg: SHA-256 differs" in report
