"""The zenoh bus: key space, message encoding, the session adapter and what joins a flight.

Only :mod:`air_sitl.bus.session` imports zenoh. Key space and encoding (the public contract,
versioned) are in :mod:`air_sitl.bus.keys` and :mod:`air_sitl.bus.codec`; ``fly`` and ``serve``
use :func:`air_sitl.bus.hookup.bus_sinks_from_args` and
:func:`air_sitl.bus.args.add_bus_arguments`.
"""

from __future__ import annotations

from air_sitl.bus.keys import CONTRACT_VERSION, DEFAULT_VEHICLE, KeySpace

__all__ = ["CONTRACT_VERSION", "DEFAULT_VEHICLE", "KeySpace"]
