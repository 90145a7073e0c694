"""Procedural surveys shared between the processes of one run through a folder (issue 34).

Drawing a procedural map is the costliest part of a frame's ground (0.3-0.5 s of CPU per
512-pixel square), and the scenarios of one area fly over the same ground: ``dataset``'s six
urban scenarios share home and their first legs. A run that flies several of them (``dataset
-j N``) gives every map one folder: the first process to draw a square saves it there, the
others read it (about 1 ms) instead of drawing it again. The pixels are those the drawing
gives, so the frames' bytes do not change.

A square is saved under a name holding its place and ground sample distance, in a folder
named after everything the drawing depends on (kind, seed, survey date and its sun, home); it
is written to a temporary name and renamed, so a reader sees a whole square or none. The
folder belongs to one run (its code, so no stale squares): the caller makes and removes it.
A square that cannot be saved (disk full) is drawn again where needed; nothing else changes.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

Bgr = npt.NDArray[np.uint8]


class SharedSurveys:
    """The squares of one procedural map date, in ``root`` / a folder of its own."""

    def __init__(self, root: Path, identity: tuple[Any, ...]) -> None:
        digest = hashlib.sha256(repr(identity).encode()).hexdigest()[:20]
        self.folder = root / f"{identity[0]}-{digest}"

    def _path(self, x0_abs: int, y0_abs: int, size: int, gsd_m: float) -> Path:
        return self.folder / f"{x0_abs}_{y0_abs}_{size}_{gsd_m!r}.npy"

    def get(self, x0_abs: int, y0_abs: int, size: int, gsd_m: float) -> Bgr | None:
        """The square saved by any process of the run, or None."""
        try:
            image: Bgr = np.load(self._path(x0_abs, y0_abs, size, gsd_m), allow_pickle=False)
        except (OSError, ValueError):
            return None
        return image

    def put(self, x0_abs: int, y0_abs: int, size: int, gsd_m: float, image: Bgr) -> None:
        """Save a square for the other processes (whole or not at all)."""
        path = self._path(x0_abs, y0_abs, size, gsd_m)
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, suffix=".part")
        except OSError:
            return
        try:
            with os.fdopen(fd, "wb") as f:
                np.save(f, image, allow_pickle=False)
            os.replace(tmp, path)
        except OSError:
            with contextlib.suppress(OSError):
                os.unlink(tmp)
