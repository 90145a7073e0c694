"""Where the bus meets by default: plain values, no zenoh, so that the command-line parsers
can show them without loading the zenoh adapter (:mod:`air_sitl.bus.session`)."""

from __future__ import annotations

DEFAULT_PORT = 7447
DEFAULT_ENDPOINT = f"tcp/127.0.0.1:{DEFAULT_PORT}"
DEFAULT_MAX_NAMES = 16  # estimators one flight hears (--max-estimate-names)
