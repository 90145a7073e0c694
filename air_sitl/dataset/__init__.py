"""AIR-compatible dataset archives: schema, crash-safe writer, reader, checker, exports.

``air_sitl.dataset.open(path)`` reads an archive (ours or an original AIR one, folder or zip)
and iterates its frames in order; see :mod:`air_sitl.dataset.reader`.
"""

from __future__ import annotations

from air_sitl.dataset.reader import AirRow, Archive, ArchiveFrame, open_archive

open = open_archive

__all__ = ["AirRow", "Archive", "ArchiveFrame", "open", "open_archive"]
