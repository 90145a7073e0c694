"""Options of a flight (fly, serve, dataset): parsed and validated once, here.

Also the validators every command's options use: numbers, integer ranges, ``A:B`` windows.
"""

from __future__ import annotations

import argparse
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from air_sitl.clock import NS_PER_S
from air_sitl.errors import OptionError
from air_sitl.fdm.base import Wind

DEFAULT_AIRCRAFT = "airsitl_uav"
OPEN_END_NS = 2**62  # the end of a GNSS denial window that lasts to the end of the flight

DenialWindows = tuple[tuple[int, int], ...]
NAV_SOURCES = ("ekf", "truth")


@dataclass(frozen=True, slots=True, kw_only=True)
class FlightOptions:
    """How to fly: aircraft, start, wind, seed, pacing, sensor noise and GNSS denial."""

    aircraft: str = DEFAULT_AIRCRAFT
    air_start: bool = False
    wind: Wind = field(default_factory=Wind)
    seed: int = 0
    speed: float = 0.0  # 0 = as fast as possible, 1 = real time
    max_sim_time_s: float = 4 * 3600.0
    sensor_noise: float = 1.0  # scale of IMU/AHRS/GNSS noise; 0 = perfect sensors
    altitude_offset_m: float = 0.0  # added to every flown altitude of the plan (builder.py)
    # GNSS denial windows [start, end) in simulation ns, sorted (OPEN_END_NS: to the end).
    gps_denied_ns: DenialWindows = ()
    # What the autopilot steers on: "ekf" (the onboard filter, air_sitl.nav.onboard; the
    # commands' default) or "truth" (the ideal: the flight model's state, byte-identical to
    # the flights before the filter was in the loop; the library's default).
    nav: str = "truth"
    # External position aid fused by the filter: an estimator name on the bus, "mavlink", or None.
    nav_aid: str | None = None
    nav_aid_sigma_m: float = 5.0  # aid 1-sigma when a measurement carries no covariance


@dataclass(frozen=True, slots=True, kw_only=True)
class MapChoice:
    """Which map the camera sees: ``spec`` is urban, forest, farmland or GeoTIFF path(s);
    None = by name."""

    spec: str | None = None
    seed: int = 0
    date: str | None = None
    dem: str | None = None  # surface model: a GeoTIFF DEM path or "builtin"; None = flat
    # A folder where the processes of one run share the procedural maps' drawn ground
    # (maps.procedural.shared_tiles; dataset makes one per run): speed only, same pixels.
    shared_dir: Path | None = None


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


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        return math.nan


def nonneg_number(name: str, text: str, *, of: str = "") -> float:
    """A finite number >= 0 (``of``: what it counts, in the message: " of seconds")."""
    value = _number(text)
    if not (math.isfinite(value) and value >= 0.0):
        msg = f"{name}: {text!r} is not a number{of} >= 0"
        raise OptionError(msg)
    return value


def positive_number(name: str, text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0.0):
        msg = f"{name}: {text!r} is not a number > 0"
        raise OptionError(msg)
    return value


def int_in_range(name: str, text: str, lo: int, hi: int) -> int:
    """An integer in ``lo..hi``."""
    try:
        value = int(text)
    except ValueError:
        value = lo - 1
    if not lo <= value <= hi:
        msg = f"{name}: {text!r} is not an integer {lo}..{hi}"
        raise OptionError(msg)
    return value


def seconds_window(name: str, text: str) -> tuple[float, float]:
    """``A:B``, two numbers of seconds >= 0 with B after A."""
    a_text, sep, b_text = text.partition(":")
    if not sep:
        msg = f"{name} {text!r}: expected A:B in simulated seconds, e.g. 60:120"
        raise OptionError(msg)
    a = nonneg_number(name, a_text, of=" of seconds")
    b = nonneg_number(name, b_text, of=" of seconds")
    if b <= a:
        msg = f"{name} {text!r}: the end must come after the start"
        raise OptionError(msg)
    return a, b


def add_flight_arguments(parser: argparse.ArgumentParser, *, default_speed: float) -> None:
    """Add --aircraft, --seed, --speed, --air-start, --wind, --turbulence, --max-sim-time,
    --sensor-noise, --altitude-offset."""
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
    g.add_argument(
        "--altitude-offset",
        default="0",
        metavar="M",
        help="shift every altitude the plan flies (take-off, waypoints, loiters, rally points) "
        "by M metres; the capture window is unchanged (default 0)",
    )
    g.add_argument(
        "--nav",
        choices=NAV_SOURCES,
        default="ekf",
        help="what the autopilot steers on: the onboard EKF fed by the simulated sensors "
        "(ekf, default, like a real aircraft) or the true state (truth, the ideal)",
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
    turbulence = nonneg_number("--turbulence", args.turbulence)
    if turbulence > 1.0:
        msg = f"--turbulence: {args.turbulence!r} must be between 0 and 1"
        raise OptionError(msg)
    wind = Wind(speed_m_s=wind.speed_m_s, from_deg=wind.from_deg, turbulence=turbulence)
    max_sim = nonneg_number("--max-sim-time", args.max_sim_time)
    offset_text = str(getattr(args, "altitude_offset", "0"))
    altitude_offset = _number(offset_text)
    if not math.isfinite(altitude_offset):
        msg = f"--altitude-offset: {offset_text!r} is not a number of metres"
        raise OptionError(msg)
    return FlightOptions(
        aircraft=args.aircraft,
        air_start=bool(args.air_start),
        wind=wind,
        seed=seed,
        speed=nonneg_number("--speed", args.speed),
        max_sim_time_s=max_sim,
        sensor_noise=nonneg_number("--sensor-noise", args.sensor_noise),
        altitude_offset_m=altitude_offset,
        gps_denied_ns=gps_denied_from_args(args),
        nav=str(getattr(args, "nav", "ekf")),
        nav_aid=nav_aid_from_args(args),
        nav_aid_sigma_m=positive_number(
            "--nav-aid-sigma", str(getattr(args, "nav_aid_sigma", "5"))
        ),
    )


def add_gps_denial_arguments(parser: argparse.ArgumentParser) -> None:
    """``--gps-denied-after``, ``--gps-denied-window`` (fly, serve)."""
    d = parser.add_argument_group("GNSS denial")
    d.add_argument(
        "--gps-denied-after",
        default=None,
        metavar="SECONDS",
        help="no GNSS fix from this simulated time (s since the start) to the end",
    )
    d.add_argument(
        "--gps-denied-window",
        action="append",
        metavar="A:B",
        help="no GNSS fix from simulated second A to B; repeatable",
    )
    d.add_argument(
        "--nav-aid",
        default=None,
        metavar="NAME",
        help="fuse the positions of the estimator NAME (estimate/NAME on zenoh; implies "
        "--zenoh) in the onboard filter, or 'mavlink' (serve: VISION_POSITION_ESTIMATE, "
        "ODOMETRY, GLOBAL_POSITION_SENSOR, GPS_INPUT from any link)",
    )
    d.add_argument(
        "--nav-aid-sigma",
        default="5",
        metavar="M",
        help="1-sigma of an aid position that carries no covariance (default 5 m)",
    )


def gps_denied_from_args(args: argparse.Namespace) -> DenialWindows:
    """GNSS denial windows [start, end) in simulation nanoseconds, sorted.

    A command without the denial options (dataset) flies without denial.
    """
    windows: list[tuple[int, int]] = []
    after = getattr(args, "gps_denied_after", None)
    if after is not None:
        start = nonneg_number("--gps-denied-after", after, of=" of seconds")
        windows.append((round(start * NS_PER_S), OPEN_END_NS))
    for text in getattr(args, "gps_denied_window", None) or ():
        a, b = seconds_window("--gps-denied-window", text)
        windows.append((round(a * NS_PER_S), round(b * NS_PER_S)))
    return tuple(sorted(windows))


def nav_aid_from_args(args: argparse.Namespace) -> str | None:
    """``--nav-aid NAME`` checked: needs ``--nav ekf`` (there is no filter to aid otherwise)."""
    name = getattr(args, "nav_aid", None)
    if name is None:
        return None
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", name):
        msg = f"--nav-aid {name!r}: expected an estimator name (letters, digits, _ . -)"
        raise OptionError(msg)
    if getattr(args, "nav", "ekf") != "ekf":
        msg = f"--nav-aid {name}: the aid is fused by the onboard filter: use it with --nav ekf"
        raise OptionError(msg)
    return str(name)
