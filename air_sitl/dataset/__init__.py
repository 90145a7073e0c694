"""AIR-compatible dataset archives: schema, crash-safe writer, reader, checker, exports.

``air_sitl.dataset.open(path)`` reads an archive (ours or an original AIR one, folder or zip)
and iterates its frames in order; see :mod:`air_sitl.dataset.reader`. The reader (OpenCV,
YAML) loads at the first use of these names: writing an archive, or flying without one,
never imports it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from air_sitl.dataset.reader import AirRow, Archive, ArchiveFrame, open_archive

    open = open_archive

__all__ = ["AirRow", "Archive", "ArchiveFrame", "open", "open_archive"]


def __getattr__(name: str) -> Any:
    """The reader's names, imported on first use."""
    if name not in __all__:
        msg = f"module {__name__!r} has no attribute {name!r}"
        raise AttributeError(msg)
    from air_sitl.dataset import reader

    value = reader.open_archive if name == "open" else getattr(reader, name)
    globals()[name] = value
    return value
