"""The one way air-sitl compiles its inner loops (numba): ``@compiled`` on a function.

numba.njit without the GIL, IEEE division (error_model "numpy": a division by zero gives inf,
no Python check per division; the code divides only by non-zero values), no fastmath (every
operation rounds as written: the same inputs give the same bytes), and machine code cached on
disk where numba finds a writable place (next to the module or in the user's cache
directory); where it finds none, compiled anew in each process rather than failing.

Importing this module imports numba (about 0.4 s): modules that need it only on some paths
import their kernels lazily.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba


def compiled(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled with the project's numba options (see the module)."""
    try:
        return numba.njit(fn, cache=True, nogil=True, error_model="numpy")
    except RuntimeError:  # numba: "cannot cache function ...: no locator available"
        return numba.njit(fn, nogil=True, error_model="numpy")


def compiled_inline(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled as :func:`compiled`, and inlined into the compiled functions that call
    it (numba's IR inlining): a small function called per pixel with arrays costs no call
    and no reference counting of its arrays (tens of nanoseconds a call otherwise)."""
    try:
        return numba.njit(fn, cache=True, nogil=True, error_model="numpy", inline="always")
    except RuntimeError:  # as in compiled
        return numba.njit(fn, nogil=True, error_model="numpy", inline="always")
