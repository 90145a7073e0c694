"""Worker processes of many runs (``dataset`` batches, sweeps): what a worker sets up first."""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import signal

_PR_SET_PDEATHSIG = 1  # prctl option: the signal this process gets when its parent dies


def die_with_parent() -> None:
    """Linux: this process gets SIGKILL when its parent dies, so a killed ``dataset`` or sweep
    leaves no orphan still writing into a folder that a resumed run is about to continue."""
    with contextlib.suppress(OSError, AttributeError):  # not Linux: no such call
        libc = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True)
        libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
