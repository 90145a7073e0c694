"""The FlightModel protocol every flight dynamics back end implements."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from air_sitl.state import ActuatorCommand, GeoPoint, VehicleState


@dataclass(frozen=True, slots=True, kw_only=True)
class Wind:
    """Steady wind (the direction it blows FROM, like a METAR) plus optional turbulence."""

    speed_m_s: float = 0.0
    from_deg: float = 0.0
    turbulence: float = 0.0  # 0 = off; otherwise JSBSim Milspec severity-like 0..1 scale


@dataclass(frozen=True, slots=True, kw_only=True)
class InitialCondition:
    """Where and how a flight starts: on the ground at rest, or in the air trimmed."""

    lat_deg: float
    lon_deg: float
    alt_amsl_m: float
    heading_rad: float
    airspeed_m_s: float = 0.0  # 0 and on_ground=True: at rest on the ground
    on_ground: bool = True


class Terrain(Protocol):
    """The ground under the flight (``--dem``), heights above mean sea level in metres.

    The ground is what the wheels roll on, the surface the first one seen from above (roofs
    and canopy included, where the model has them; a DEM file is both).
    :class:`~air_sitl.maps.surface.SurfaceModel` is one.
    """

    def ground_and_surface_at(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        """Heights of the ground and of the first surface under a position."""
        ...

    def height_at(self, lat_deg: float, lon_deg: float) -> float:
        """Height of the first surface under a position."""
        ...


class FlightModel(Protocol):
    """A fixed-step flight dynamics model.

    ``ground`` is the home point and ``pos_ned_m`` in states is relative to it. Without a
    :class:`Terrain` the ground elevation is ``ground.alt_amsl_m`` everywhere; with one, the
    wheels meet the terrain under the aircraft and states carry the surface beneath it.
    """

    step_ns: int

    def reset(self, ground: GeoPoint, initial: InitialCondition, wind: Wind) -> VehicleState:
        """Place the aircraft (trimmed when airborne) and return the state at time 0."""
        ...

    def step(self, command: ActuatorCommand) -> VehicleState:
        """Apply ``command`` and advance one step of ``step_ns``; return the new state."""
        ...
