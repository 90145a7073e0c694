"""Errors of the scoring package: bad estimate input, an archive without truth."""

from __future__ import annotations

from air_sitl.errors import AirSitlError


class EvalError(AirSitlError):
    """An estimate source or an archive cannot be scored: one line naming file, line, value."""
