"""Foxglove: the live view (``--foxglove``) and MCAP recordings (``export --mcap``).

:mod:`air_sitl.foxglove.topics` builds every message from the project's own types, so a live
flight and a recorded one carry the same topics; only this package imports ``foxglove-sdk``
(an extra: ``pip install 'air-sitl[foxglove]'``).
"""

from __future__ import annotations

from air_sitl.errors import OptionError

INSTALL_HINT = "pip install 'air-sitl[foxglove]'"


def require_sdk(option: str) -> None:
    """OptionError (one line, naming the install command) when foxglove-sdk is missing."""
    try:
        import foxglove  # noqa: F401
    except ImportError:
        msg = f"{option}: needs the Foxglove SDK, which is not installed ({INSTALL_HINT})"
        raise OptionError(msg) from None
