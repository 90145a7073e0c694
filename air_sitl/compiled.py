"""The one way air-sitl compiles its inner loops (numba): ``@compiled`` on a function.

numba.njit without the GIL, IEEE division (error_model "numpy": a division by zero gives inf,
no Python check per division; the code divides only by non-zero values), no fastmath (every
operation rounds as written: the same inputs give the same bytes), and machine code cached on
disk where numba finds a writable place (next to the module or in the user's cache
directory); where it finds none, compiled anew in each process rather than failing.

Importing this module imports numba (about 0.4 s): modules that need it only on some paths
import their kernels lazily. Numba's numpy support, loaded at its first compile, would also
import scipy.linalg (0.3 s) just to see whether ``np.dot`` may call BLAS; it loads here with
that look-up answered "no" (our kernels call no BLAS; numba's linear algebra still imports
scipy itself where a kernel uses it).
"""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from typing import Any

import numba


def _numpy_support_without_scipy() -> None:
    """Load ``numba.np.arraymath`` with ``scipy.linalg.cython_blas`` unimportable for the
    moment of its BLAS check (nothing is hidden when scipy.linalg is loaded already)."""
    blas = "scipy.linalg.cython_blas"
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return
    sys.modules[blas] = None  # type: ignore[assignment]  # an import of it raises ImportError
    try:
        import numba.np.arraymath  # noqa: F401
    except ImportError:  # another numba's layout: it loads its own way at the first compile
        pass
    finally:
        del sys.modules[blas]


_numpy_support_without_scipy()


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


def never_compiled(*functions: Any) -> bool:
    """Whether numba's disk cache lacks the machine code of one of ``functions`` (made with
    :func:`compiled`): their first call will compile them (seconds each) rather than load
    them. False where numba cannot say (no cache, another numba's layout)."""
    for fn in functions:
        index = getattr(
            getattr(getattr(fn, "_cache", None), "_cache_file", None), "_index_path", None
        )
        if isinstance(index, str) and not os.path.exists(index):
            return True
    return False


def say_when_compiling(what: str, *functions: Any) -> None:
    """One line on a terminal before ``functions`` are compiled for the first time on this
    machine (the first flight after an install sits half a minute in it otherwise); nothing
    where stderr is not a terminal (scripts, tests, workers' pipes) or the code is cached."""
    if sys.stderr.isatty() and never_compiled(*functions):
        print(
            f"air-sitl: compiling {what} for this machine, once (about half a minute; "
            "later runs load it)",
            file=sys.stderr,
            flush=True,
        )
