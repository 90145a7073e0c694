"""Procedural surveys shared between the processes of one run through a folder (issue 34).

Drawing a procedural map is the costliest part of a frame's ground (0.3-0.5 s of CPU per
512-pixel square), and the scenarios of one area fly over the same ground: ``dataset``'s six
urban scenarios share home and their first legs. A run that flies several of them (``dataset
-j N``) gives every map one folder: the first process to draw a square saves it there, the
others read it (about 1 ms) instead of drawing it again. The pixels are those the drawing
gives, so the frames' bytes do not change.

A square is saved under a name holding its place and ground sample distance, in a folder
named after everything the drawing depends on (kind, seed, survey date and its sun, home); it
is written to a temporary name and renamed, so a reader sees a whole square or none; a claim
file beside it tells the others it is being drawn. The folder belongs to one run (its code,
so no stale squares): the caller makes and removes it. A square that cannot be saved (disk
full) is drawn again where needed; nothing else changes.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

Bgr = npt.NDArray[np.uint8]
PREFIX = "air-sitl-ground-"  # the run's folders in the system's temporary folder: PREFIX<pid>-*
WAIT_S = 30.0  # longest wait for a square another process draws (a drawing takes 0.3-0.6 s)
POLL_S = 0.01


@contextlib.contextmanager
def shared_folder() -> Iterator[Path]:
    """A folder for one run's processes to share the drawn ground, removed after the run;
    the folders of runs whose process is gone (killed: nothing removed them) go first."""
    base = Path(tempfile.gettempdir())
    for old in base.glob(f"{PREFIX}*"):
        pid = old.name[len(PREFIX) :].split("-", 1)[0]
        if pid.isdigit() and not _alive(int(pid)):
            shutil.rmtree(old, ignore_errors=True)
    folder = Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-"))
    try:
        yield folder
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


class SharedSurveys:
    """The squares of one procedural map date, in ``root`` / a folder of its own."""

    def __init__(self, root: Path, identity: tuple[Any, ...]) -> None:
        digest = hashlib.sha256(repr(identity).encode()).hexdigest()[:20]
        self.folder = root / f"{identity[0]}-{digest}"

    def square(
        self, x0_abs: int, y0_abs: int, size: int, gsd_m: float, draw: Callable[[], Bgr]
    ) -> Bgr:
        """The square saved by any process of the run; else ``draw()``'s, saved for the
        others. While another process (or thread) draws it, wait for it rather than drawing
        it twice (two scenarios of one area fly the same first legs at the same time); one
        that has not saved it after WAIT_S (it died) is drawn here."""
        path = self.folder / f"{x0_abs}_{y0_abs}_{size}_{gsd_m!r}.npy"
        if (saved := _load(path)) is not None:
            return saved
        claim = path.with_suffix(".drawing")
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            os.close(os.open(claim, os.O_CREAT | os.O_EXCL | os.O_WRONLY))
        except FileExistsError:
            deadline = time.monotonic() + WAIT_S
            while time.monotonic() < deadline:
                time.sleep(POLL_S)
                if (saved := _load(path)) is not None:
                    return saved
                if not claim.exists():  # the drawer gave up (could not save)
                    break
            saved = _load(path)
            return saved if saved is not None else draw()
        except OSError:
            return draw()  # no folder to share through: draw alone
        try:
            image = draw()
            _save(path, image)
        finally:
            with contextlib.suppress(OSError):
                os.unlink(claim)
        return image


def _load(path: Path) -> Bgr | None:
    try:
        image: Bgr = np.load(path, allow_pickle=False)
    except (OSError, ValueError):
        return None
    return image


def _save(path: Path, image: Bgr) -> None:
    """Write ``image`` whole to ``path`` or not at all (a full disk only costs the others a
    drawing of their own)."""
    try:
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".part")
    except OSError:
        return
    try:
        with os.fdopen(fd, "wb") as f:
            np.save(f, image, allow_pickle=False)
        os.replace(tmp, path)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
