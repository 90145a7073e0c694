"""Errors of the sweep package: a SPEC that cannot be run, a results file that cannot be read."""

from __future__ import annotations

from air_sitl.errors import AirSitlError


class SweepError(AirSitlError):
    """A SPEC or a sweep folder is unusable: one line naming the file, the key and the value."""
