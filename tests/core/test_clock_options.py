"""Clock, pacing and the shared flight options."""

from __future__ import annotations

import argparse
import time

import pytest

from air_sitl.clock import CAMERA_PERIOD_NS, PHYSICS_STEP_NS, Pacer, SimClock
from air_sitl.errors import OptionError
from air_sitl.options import add_flight_arguments, flight_options_from_args, parse_wind


def test_physics_step_divides_camera_period() -> None:
    assert CAMERA_PERIOD_NS % PHYSICS_STEP_NS == 0
    clock = SimClock()
    ticks = [clock.tick() for _ in range(8)]
    assert ticks[-1] == 8 * PHYSICS_STEP_NS
    assert [t for t in ticks if t % CAMERA_PERIOD_NS == 0] == [
        CAMERA_PERIOD_NS,
        2 * CAMERA_PERIOD_NS,
    ]


def test_pacer_holds_real_time_at_speed_4() -> None:
    pacer = Pacer(4.0)
    start = time.monotonic()
    for k in range(0, 41):
        pacer.wait(k * 10_000_000)  # 0.4 s simulated in 10 ms steps
    wall = time.monotonic() - start
    assert 0.09 <= wall < 0.3


def test_pacer_speed_zero_never_waits() -> None:
    pacer = Pacer(0.0)
    start = time.monotonic()
    for k in range(1000):
        pacer.wait(k * 1_000_000_000)
    assert time.monotonic() - start < 0.1


@pytest.mark.parametrize("bad", [-1.0, float("nan"), float("inf")])
def test_pacer_refuses_bad_speed(bad: float) -> None:
    with pytest.raises(OptionError, match="--speed"):
        Pacer(bad)


def test_parse_wind() -> None:
    w = parse_wind("5@270")
    assert (w.speed_m_s, w.from_deg) == (5.0, 270.0)
    assert parse_wind(" 3.5 @ 370 ").from_deg == 10.0
    for bad in ["5", "fast@north", "50@10", "nan@3"]:
        with pytest.raises(OptionError, match="--wind"):
            parse_wind(bad)


def _parse(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_flight_arguments(parser, default_speed=0.0)
    return parser.parse_args(list(argv))


def test_flight_options_from_args() -> None:
    opts = flight_options_from_args(_parse("--seed", "7", "--wind", "4@90", "--air-start"))
    assert opts.seed == 7
    assert opts.air_start
    assert opts.wind.speed_m_s == 4.0
    assert opts.speed == 0.0
    for argv, name in [
        (("--seed", "x"), "--seed"),
        (("--seed", "-3"), "--seed"),
        (("--speed", "fast"), "--speed"),
        (("--turbulence", "2"), "--turbulence"),
    ]:
        with pytest.raises(OptionError, match=name):
            flight_options_from_args(_parse(*argv))
