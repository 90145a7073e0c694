"""The boundary between guidance (what to fly) and control (how to move the surfaces)."""

from __future__ import annotations

import enum
import math
from collections.abc import Callable
from dataclasses import dataclass

from air_sitl.state import positional_builder


class ControlPhase(enum.Enum):
    """Which control law the controller runs."""

    IDLE = "idle"  # on the ground: throttle 0, brakes on, surfaces neutral
    GROUND_ROLL = "ground_roll"  # take-off run: full throttle, steer heading, rotate at speed
    CLIMB = "climb"  # climb-out: climb throttle, wings level-ish, pitch for airspeed
    CRUISE = "cruise"  # total-energy speed/height control plus roll tracking
    LAND = "land"  # glide: throttle idle, hold approach airspeed/glide slope, flare, roll out


@dataclass(frozen=True, slots=True, kw_only=True)
class ControlTarget:
    """What guidance asks of the controller at one instant."""

    phase: ControlPhase
    roll_rad: float = 0.0  # commanded bank (positive = right wing down)
    altitude_amsl_m: float = 0.0
    airspeed_m_s: float = 15.0
    heading_rad: float = 0.0  # used on the ground (GROUND_ROLL) and for the roll-out
    climb_rate_limit_m_s: float = 3.0  # max climb / sink rate demanded by the height loop
    # LAND (required there): the ground the landing flares above (the DEM's at the touchdown
    # point, else home's).
    ground_amsl_m: float = math.nan
    # Pitch limits from the parameters (FW_P_LIM_MAX/MIN); the controller also keeps its own.
    pitch_max_rad: float = math.pi / 2
    pitch_min_rad: float = -math.pi / 2


# Built by guidance at 50 Hz, positionally (fields in declared order).
control_target: Callable[..., ControlTarget] = positional_builder(ControlTarget)
