"""Lockstep with an estimator (real camera, real sessions): order, logging, and a silent peer."""

from __future__ import annotations

import csv
import time
from pathlib import Path

import pytest

from air_sitl.bus import codec
from air_sitl.bus.estimates import ESTIMATE_COLUMNS, EstimateLog
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.lockstep import LockstepFrameSource, WaitFor
from air_sitl.bus.publisher import BusPublisher, FrameLedger, PublishOptions
from air_sitl.bus.session import Bus, Message
from air_sitl.camera.bridge import CameraBridge
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.errors import BusError
from air_sitl.maps.open import open_map

from .helpers import HOME, free_endpoint, make_sample, pair, wait_until

KEYS = KeySpace("ls")
CAMERA = CameraModel(width_px=160, height_px=120)


def camera() -> CameraBridge:
    return CameraBridge(Renderer(open_map("urban", HOME), CAMERA, seed=1), workers=2)


def answer_frames(bus: Bus, name: str, delay_s: float, seen: list[int]) -> None:
    """A minimal estimator: answers each frame with the position it was told (ENU)."""
    pub = bus.publisher(KEYS.estimate(name), encoding=codec.JSON_ENCODING, block=True)

    def on_image(m: Message) -> None:
        meta = codec.decode_frame_meta(m.attachment)
        seen.append(meta.frame)
        time.sleep(delay_s)
        pub.put(codec.encode_estimate(frame=meta.frame, enu_m=(15.0 * meta.frame, 0.0, 200.0)))

    bus.subscribe(KEYS.image, on_image)


def setup(sim: Bus, out: Path | None, lag: int, timeout_s: float) -> tuple[
    BusPublisher, EstimateLog, LockstepFrameSource
]:  # fmt: skip
    ledger = FrameLedger()
    pub = BusPublisher(sim, PublishOptions(keys=KEYS, home=HOME, block_frames=True), ledger)
    log = EstimateLog(sim, KEYS, ledger, out_dir=out, home=HOME)
    source = LockstepFrameSource(
        camera(),
        wait=WaitFor("ex", lag, timeout_s),
        publish=pub.publish_frame,
        ledger=ledger,
        log=log,
        image_key=KEYS.image,
        subscriber_present=lambda: pub.image_matched,
    )
    return pub, log, source


@pytest.mark.parametrize("lag", [1, 3])
def test_frame_k_plus_lag_waits_for_the_estimate_of_frame_k(tmp_path: Path, lag: int) -> None:
    sim, est = pair(free_endpoint())
    with sim, est:
        seen: list[int] = []
        answer_frames(est, "ex", 0.005, seen)
        pub, log, source = setup(sim, tmp_path, lag, 5.0)
        delivered = []
        n = 40
        for k in range(n):
            sample = make_sample(k * CAMERA_PERIOD_NS, east_m=0.3 * k)
            pub.on_sample(sample)
            source.submit(sample, k)
            if k >= lag:
                assert log.has("ex", k - lag), f"frame {k} rendered before estimate {k - lag}"
            if k + 1 < n:
                assert not log.has("ex", k + 1)
            for frame in source.ready():
                pub.on_frame(frame)
                delivered.append(frame.index)
        for frame in source.flush():
            pub.on_frame(frame)
            delivered.append(frame.index)
        source.close()
        assert delivered == list(range(n))
        assert all(log.has("ex", k) for k in range(n))
        assert pub.frames_published == n and seen == list(range(n))
        log.close()
    with (tmp_path / "estimates" / "ex.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == list(ESTIMATE_COLUMNS)
    assert [int(r["frame"]) for r in rows] == list(range(n))
    assert [int(r["sim_time_ns"]) for r in rows] == [k * CAMERA_PERIOD_NS for k in range(n)]
    assert float(rows[10]["east_m"]) == 150.0 and float(rows[10]["up_m"]) == 200.0
    assert abs(float(rows[0]["lat_deg"]) - HOME.lat_deg) < 1e-6
    assert abs(float(rows[0]["alt_amsl_m"]) - (HOME.alt_amsl_m + 200.0)) < 0.01
    assert all(float(r["latency_wall_ms"]) >= 5.0 for r in rows)  # the estimator sleeps 5 ms
    assert all(0 <= int(r["latency_frames"]) < lag for r in rows)


def test_a_silent_estimator_stops_the_run_after_the_timeout() -> None:
    sim, est = pair(free_endpoint())
    with sim, est:
        est.subscribe(KEYS.image, lambda m: None)  # listens, never answers
        pub, _log, source = setup(sim, None, 1, 0.5)
        start = time.monotonic()
        with pytest.raises(BusError, match=r"--wait-for ex: no estimate for frame 0 within 0\.5 s"):
            for k in range(5):
                sample = make_sample(k * CAMERA_PERIOD_NS)
                pub.on_sample(sample)
                source.submit(sample, k)
        # It waited the whole --wait-for timeout (a wall-clock option by definition) first.
        assert time.monotonic() - start >= 0.5
        source.close()


def test_nobody_listening_is_an_error_too() -> None:
    sim, est = pair(free_endpoint())
    with sim, est:
        _pub, _log, source = setup(sim, None, 1, 0.3)
        with pytest.raises(BusError, match="nobody subscribed to air/ls/camera/image"):
            for k in range(3):
                sample = make_sample(k * CAMERA_PERIOD_NS)
                source.submit(sample, k)
        source.close()


def test_estimates_by_timestamp_map_to_frames_and_bad_ones_are_counted(tmp_path: Path) -> None:
    sim, est = pair(free_endpoint())
    with sim, est:
        ledger = FrameLedger()
        log = EstimateLog(sim, KEYS, ledger, out_dir=tmp_path, home=HOME)
        ledger.record(0, 0, 0)
        ledger.record(1, CAMERA_PERIOD_NS, 1)
        out = est.publisher(KEYS.estimate("ts"), encoding=codec.JSON_ENCODING)
        assert wait_until(lambda: out.matched)
        out.put(codec.encode_estimate(sim_time_ns=CAMERA_PERIOD_NS, enu_m=(1.0, 2.0, 3.0)))
        out.put(b'{"enu_m": [1, 2, 3]}')
        assert wait_until(lambda: log.has("ts", 1) and log.rejected_total() == 1)
        assert log.rejected == {"no_frame_or_time": 1}
        assert "needs 'frame' or 'sim_time_ns'" in (log.first_error or "")
        assert log.positions_enu("ts") == {1: (1.0, 2.0, 3.0)}
        log.close()
