"""One base error for everything a user can cause; the CLI prints it as one line.

Messages name the file (or source), the item and the value, and say what was expected:
``"missions/FL-200.plan: item 3: latitude 91.0 is outside [-90, 90]"``.
"""

from __future__ import annotations


class AirSitlError(Exception):
    """A user-facing error: bad input, bad configuration, unusable environment.

    The CLI turns it into ``air-sitl: error: <message>`` on stderr and exits with
    :attr:`exit_code`; anything that is not an ``AirSitlError`` is a bug and keeps its traceback.
    """

    exit_code = 2


class PlanError(AirSitlError):
    """A mission plan (.plan JSON, QGC WPL, MAVLink upload) is unreadable or invalid."""


class AircraftError(AirSitlError):
    """An aircraft model cannot be found or loaded."""


class MapError(AirSitlError):
    """A map source is missing, not georeferenced, or does not cover the flight."""


class CameraError(AirSitlError):
    """A camera configuration is invalid."""


class DatasetError(AirSitlError):
    """A dataset archive cannot be written, read or validated."""


class MavlinkError(AirSitlError):
    """A MAVLink link cannot be opened or is misconfigured."""


class BusError(AirSitlError):
    """The zenoh bus cannot be opened, or a peer stopped answering."""


class OptionError(AirSitlError):
    """A command-line option has a value that cannot be used."""
