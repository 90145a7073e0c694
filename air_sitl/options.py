"""Options shared by the commands that fly a vehicle (fly, serve, dataset): parse once, here."""

from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass, field

from air_sitl.errors import OptionError
from air_sitl.fdm.base import Wind

DEFAULT_AIRCRAFT = "airsitl_uav"


@dataclass(frozen=True, slots=True, kw_only=True)
class FlightOptions:
    """How to fly: aircraft, start, wind, seed and pacing."""

    aircraft: str = DEFAULT_AIRCRAFT
    air_start: bool = False
    wind: Wind = field(default_factory=Wind)
    seed: int = 0
    speed: float = 0.0  # 0 = as fast as possible, 1 = real time
    max_sim_time_s: float = 4 * 3600.0
    sensor_noise: float = 1.0  # scale of IMU/AHRS/GNSS noise; 0 = perfect sensors


def parse_wind(text: str) -> Wind:
    """``SPEED_M_S@FROM_DEG`` (steady wind blowing from FROM_DEG), e.g. ``5@270``."""
    m = re.fullmatch(r"\s*([0-9.eE+-]+)\s*@\s*([0-9.eE+-]+)\s*", text)
    if m is None:
        msg = f"--wind: {text!r} is not SPEED_M_S@FROM_DEG (for example 5@270)"
        raise OptionError(msg)
    try:
        speed, direction = float(m.group(1)), float(m.group(2))
    except ValueError:
        msg = f"--wind: {text!r} is not SPEED_M_S@FROM_DEG (for example 5@270)"
        raise OptionError(msg) from None
    if not (math.isfinite(speed) and 0.0 <= speed <= 30.0 and math.isfinite(direction)):
        msg = f"--wind: {text!r}: speed must be 0..30 m/s and the direction a finite angle"
        raise OptionError(msg)
    return Wind(speed_m_s=speed, from_deg=direction % 360.0)


def _nonneg_float(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0.0):
        msg = f"{name}: {text!r} is not a number >= 0"
        raise OptionError(msg)
    return value


def add_flight_arguments(parser: argparse.ArgumentParser, *, default_speed: float) -> None:
    """Add --aircraft, --seed, --speed, --air-start, --wind, --turbulence, --max-sim-time."""
    g = parser.add_argument_group("flight")
    g.add_argument(
        "--aircraft",
        default=DEFAULT_AIRCRAFT,
        help="our UAV 'airsitl_uav' (default) or any aircraft the jsbsim package ships "
        "(c172p, J3Cub ...)",
    )
    g.add_argument("--seed", default="0", help="seed of every random process (default 0)")
    g.add_argument(
        "--speed",
        default=str(default_speed),
        help="simulated seconds per wall second; 0 = as fast as possible "
        f"(default {default_speed:g})",
    )
    g.add_argument(
        "--air-start",
        action="store_true",
        help="start in the air at the first waypoint after take-off, at cruise altitude and speed",
    )
    g.add_argument("--wind", default=None, help="steady wind SPEED_M_S@FROM_DEG, e.g. 5@270")
    g.add_argument("--turbulence", default="0", help="turbulence intensity 0..1 (default 0: off)")
    g.add_argument(
        "--max-sim-time",
        default="14400",
        help="give up after this many simulated seconds (default 14400)",
    )
    g.add_argument(
        "--sensor-noise",
        default="1",
        help="scale of IMU/AHRS/GNSS noise; 0 = perfect sensors (default 1)",
    )


def flight_options_from_args(args: argparse.Namespace) -> FlightOptions:
    """Validate the flight arguments into FlightOptions (OptionError on bad values)."""
    try:
        seed = int(args.seed)
    except ValueError:
        msg = f"--seed: {args.seed!r} is not an integer"
        raise OptionError(msg) from None
    if seed < 0:
        msg = f"--seed: {seed} must be >= 0"
        raise OptionError(msg)
    wind = parse_wind(args.wind) if args.wind else Wind()
    turbulence = _nonneg_float("--turbulence", args.turbulence)
    if turbulence > 1.0:
        msg = f"--turbulence: {args.turbulence!r} must be between 0 and 1"
        raise OptionError(msg)
    wind = Wind(speed_m_s=wind.speed_m_s, from_deg=wind.from_deg, turbulence=turbulence)
    max_sim = _nonneg_float("--max-sim-time", args.max_sim_time)
    return FlightOptions(
        aircraft=args.aircraft,
        air_start=bool(args.air_start),
        wind=wind,
        seed=seed,
        speed=_nonneg_float("--speed", args.speed),
        max_sim_time_s=max_sim,
        sensor_noise=_nonneg_float("--sensor-noise", args.sensor_noise),
    )
