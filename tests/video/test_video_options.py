"""serve's video and instance options: defaults as PX4 SITL, one clear line for a bad value."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest
import yaml
from bus.helpers import free_endpoint
from cli_errors import one_line_error

from air_sitl import serving
from air_sitl.cli import build_parser
from air_sitl.commands import serve
from air_sitl.instance import instance_from_args
from air_sitl.video.options import video_options_from_args

REPO = Path(__file__).resolve().parents[2]


def _parse(*argv: str) -> tuple[object, object]:
    args = build_parser().parse_args(["serve", *argv])
    instance = instance_from_args(args)
    return instance, video_options_from_args(args, default_port=instance.video_port)


def test_defaults_are_px4_sitls() -> None:
    instance, video = _parse()
    assert instance.system_id == 1  # type: ignore[attr-defined]
    assert instance.links == ("udpout:127.0.0.1:14550", "udpout:127.0.0.1:14540")  # type: ignore[attr-defined]
    assert video.url == "udp://127.0.0.1:5600"  # type: ignore[attr-defined]
    assert (video.fps, video.bitrate_bps, video.overlay) == (30.0, 6_000_000, False)  # type: ignore[attr-defined]


def test_instance_n_moves_every_port_and_the_system_id() -> None:
    instance, video = _parse("--instance", "3", "--video-bitrate", "2500k", "--video-fps", "25")
    assert instance.system_id == 4 and instance.vehicle_name == "uav3"  # type: ignore[attr-defined]
    assert instance.links == ("udpout:127.0.0.1:14550", "udpout:127.0.0.1:14543")  # type: ignore[attr-defined]
    assert video.url == "udp://127.0.0.1:5603"  # type: ignore[attr-defined]
    assert (video.fps, video.bitrate_bps) == (25.0, 2_500_000)  # type: ignore[attr-defined]
    _, explicit = _parse("--instance", "3", "--video", "udp://10.0.0.5:6000")
    assert explicit.url == "udp://10.0.0.5:6000"  # type: ignore[attr-defined]
    assert explicit.viewer_uri == "udp://0.0.0.0:6000"  # type: ignore[attr-defined]
    _, off = _parse("--no-video")
    assert off is None


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["--video", "tcp://127.0.0.1:5600"], "--video 'tcp://127.0.0.1:5600'"),
        (["--video", "udp://127.0.0.1:70000"], "port 70000"),
        (["--video-fps", "0"], "--video-fps '0'"),
        (["--video-fps", "fast"], "--video-fps 'fast'"),
        (["--video-bitrate", "4G"], "--video-bitrate '4G'"),
        (["--no-video", "--video", "udp://127.0.0.1:5600"], "--no-video"),
        (["--instance", "300"], "--instance 300"),
        (["--instance", "2", "--video-base-port", "65534"], "--video-base-port 65534"),
    ],
)
def test_a_bad_value_is_one_line(
    argv: list[str], names: str, capsys: pytest.CaptureFixture[str]
) -> None:
    err = one_line_error(["serve", "--mavlink", "udpin:127.0.0.1:0", *argv], capsys)
    assert names in err


def test_the_compose_two_vehicle_example_gives_each_vehicle_its_own_identity() -> None:
    compose = yaml.safe_load((REPO / "docker-compose.yml").read_text(encoding="utf-8"))
    served = [
        build_parser().parse_args(s["command"][1:])
        for s in compose["services"].values()
        if "--instance" in s["command"]
    ]
    assert len(served) == 2
    instances = [instance_from_args(a) for a in served]
    assert sorted(i.system_id for i in instances) == [1, 2]
    for args, instance in zip(served, instances, strict=True):
        video = video_options_from_args(args, default_port=instance.video_port)
        assert video is not None and video.port == 5600 + instance.number
    assert len({tuple(a.mavlink) for a in served}) == 2


@pytest.mark.parametrize(
    ("argv", "vehicle"),
    [([], "uav0"), (["--instance", "2"], "uav2"), (["--instance", "2", "--vehicle", "red"], "red")],
)
def test_instance_n_publishes_under_air_uav_n(
    monkeypatch: pytest.MonkeyPatch, argv: list[str], vehicle: str
) -> None:
    seen: dict[str, Any] = {}

    def fake_serve(setup: object, specs: object, **kw: Any) -> object:
        seen.update(kw, vehicle=kw["bus"].options.keys.vehicle)
        return SimpleNamespace(messages=0, dropped=0, parse_errors=0, unknown_ids=0,
                               signature_rejected=0)  # fmt: skip

    monkeypatch.setattr(serving, "serve_vehicle", fake_serve)
    args = build_parser().parse_args(["serve", "--quiet", "--zenoh", "--zenoh-listen",
                                      free_endpoint(), *argv])  # fmt: skip
    assert serve.run(args) == 0
    assert seen["vehicle"] == vehicle
    assert seen["system_id"] == (3 if "2" in argv else 1)
