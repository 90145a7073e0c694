"""The one way air-sitl compiles its inner loops (numba): ``@compiled`` on a function.

numba.njit without the GIL, IEEE division (error_model "numpy": a division by zero gives inf,
no Python check per division; the code divides only by non-zero values), no fastmath (every
operation rounds as written: the same inputs give the same bytes).

**Machine code built ahead of time.** The kernel modules of a group (:data:`GROUPS`: the
navigation filter, the relief renderer, the camera effects) are compiled together into one
extension module by numba's ahead-of-time compiler (``numba.pycc``, from the same Python
source, with the same options, for this CPU: :mod:`air_sitl.compiled_build`), once per
machine and version. Its functions are the kernels given a signature next to them
(``@compiled("f8(f8[:, ::1])")``, numba's notation: the types its JIT infers from the
callers' arguments; ``::1`` a contiguous dimension); the others are compiled into the
kernels that call them and are not callable from Python then. A process whose group is
built loads it (milliseconds) and never imports numba (0.5 s of CPU, and up to 0.3 s more
loading numba's cached machine code of a group). The first process to need a build makes
it (half a minute; one line on a terminal) while the others wait for it; where none can be
made (no C compiler or Python headers, no writable cache, a numba without ``pycc``, a failed
build), or with ``AIR_SITL_JIT=1``: numba's JIT, as before, with the same bytes.

numba's JIT caches its machine code on disk where it finds a writable place (next to the
module or in the user's cache directory), else compiles anew in each process rather than
failing. Its numpy support, loaded at its first compile, would also import scipy.linalg
(0.3 s) just to see whether ``np.dot`` may call BLAS; it loads here with that look-up
answered "no" (our kernels call no BLAS; numba's linear algebra still imports scipy itself
where a kernel uses it).

``AIR_SITL_CHECK_KERNELS=1`` (the tests set it) checks each call of a built kernel against
its signature: an array of another type, rank or layout (a view where a contiguous array is
declared) is an error there, where numba's JIT would compile another version and the built
code would read the memory wrongly.
"""

from __future__ import annotations

import functools
import os
import re
import sys
from collections.abc import Callable
from dataclasses import dataclass
from types import ModuleType
from typing import Any, overload

from air_sitl import compiled_build


@dataclass(frozen=True, slots=True)
class Group:
    """Kernel modules built into one extension module; ``what`` names them to a user."""

    what: str
    modules: tuple[str, ...]


GROUPS = {
    "nav": Group("the navigation filter",
                 ("air_sitl.nav.quaternion", "air_sitl.nav.kernels", "air_sitl.nav.strapdown",
                  "air_sitl.nav.geodetic")),
    "relief": Group("the relief renderer", ("air_sitl.camera.relief_march",)),
    "effects": Group("the camera effects", ("air_sitl.camera.effects_kernel",
                                             "air_sitl.camera.effects_pixels_kernel")),
    "flight": Group("the flight loop", ("air_sitl.autopilot.control_kernel",
                                        "air_sitl.sensors_kernel", "air_sitl.battery_kernel",
                                        "air_sitl.fdm.state_kernel", "air_sitl.text_kernel")),
}  # fmt: skip
_GROUP_OF = {module: name for name, group in GROUPS.items() for module in group.modules}


@overload
def compiled(kernel: Callable[..., Any], /) -> Any: ...
@overload
def compiled(kernel: str, /) -> Callable[[Callable[..., Any]], Any]: ...
def compiled(kernel: Callable[..., Any] | str, /) -> Any:
    """``@compiled`` or ``@compiled("signature")``: the function compiled with the project's
    numba options, or its machine code from its group's build (see the module)."""
    if callable(kernel):
        return _kernel(kernel, None, inline=False)
    return functools.partial(_kernel, signature=kernel, inline=False)


def compiled_inline(fn: Callable[..., Any]) -> Any:
    """``fn`` compiled as :func:`compiled`, and inlined into the compiled functions that call
    it (numba's IR inlining): a small function called per pixel with arrays costs no call
    and no reference counting of its arrays (tens of nanoseconds a call otherwise)."""
    return _kernel(fn, None, inline=True)


def machine_code(group: str) -> ModuleType | None:
    """``group``'s built extension module (built now if needed); None where numba's JIT
    compiles its kernels."""
    if os.environ.get("AIR_SITL_JIT", "") not in ("", "0"):
        return None
    return compiled_build.machine_code(group, GROUPS[group].modules, GROUPS[group].what)


def build_all() -> None:
    """Every group's build made now where missing, the groups side by side (the test
    suite's controller calls this before its workers start)."""
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(len(GROUPS)) as pool:
        list(pool.map(machine_code, GROUPS))


def _kernel(fn: Callable[..., Any], signature: str | None, *, inline: bool) -> Any:
    group = _GROUP_OF.get(fn.__module__)
    if group is not None and os.environ.get(compiled_build.BUILDING):
        kernel = _jit(fn, inline=inline, cache=False)
        kernel.exported_signature = signature  # what the builder exports
        return kernel
    built = machine_code(group) if group is not None else None
    if built is None:
        return _jit(fn, inline=inline, cache=True)
    if signature is None:
        return _Internal(fn)
    kernel = getattr(built, compiled_build.symbol(fn.__module__, fn.__name__))
    if os.environ.get("AIR_SITL_CHECK_KERNELS", "") not in ("", "0"):
        return _Checked(kernel, signature)
    return kernel


class _Internal:
    """A kernel without signature where its group is built: compiled into its callers."""

    def __init__(self, fn: Callable[..., Any]) -> None:
        self.__wrapped__ = fn
        self.__name__ = fn.__name__

    def __call__(self, *args: Any) -> Any:
        raise TypeError(
            f"{self.__wrapped__.__module__}.{self.__name__} has no signature: it is compiled "
            "into the kernels that call it (give it one to call it from Python, or set "
            "AIR_SITL_JIT=1)"
        )


_DTYPES = {"f8": "float64", "f4": "float32", "i8": "int64", "u1": "uint8", "b1": "bool"}


class _Checked:
    """A built kernel whose calls are checked against its signature (the arrays' type,
    rank and contiguity, the scalars' kind) before they run. Each argument's test is made
    once, here: the tests run every flight with the check on, at 200 calls a second of
    simulation for each of the flight loop's kernels."""

    def __init__(self, kernel: Callable[..., Any], signature: str) -> None:
        self.kernel = kernel
        self.__name__ = kernel.__name__
        self.signature = signature
        self.args = _argument_types(signature)
        self._fits = tuple(_argument_test(*arg) for arg in self.args)

    def __call__(self, *args: Any) -> Any:
        if len(args) != len(self._fits):
            raise TypeError(f"{self.__name__}{self.signature}: {len(args)} arguments given")
        for fits, arg in zip(self._fits, args, strict=True):
            if not fits(arg):
                self._refuse(args)
        return self.kernel(*args)

    def _refuse(self, args: tuple[Any, ...]) -> None:
        import numpy as np

        k, arg = next(
            (k, a) for k, (f, a) in enumerate(zip(self._fits, args, strict=True)) if not f(a)
        )
        what = f"{type(arg).__name__}"
        if isinstance(arg, np.ndarray):
            layout = "contiguous" if arg.flags.c_contiguous else "a view"
            what = f"{arg.dtype} array of rank {arg.ndim}, {layout}"
        raise TypeError(f"{self.__name__}{self.signature}: argument {k + 1} is {what}")


def _argument_test(kind: str, rank: int, contiguous: bool) -> Callable[[Any], bool]:
    """Whether a value may be passed as an argument of this numpy type, rank (0: a scalar)
    and contiguity."""
    import numpy as np

    if rank == 0:
        if kind == "float64":
            numbers = (float, int, np.floating, np.integer)
            return lambda a: type(a) is float or isinstance(a, numbers)
        if kind == "int64":
            integers = (int, np.integer)
            return lambda a: type(a) is int or (isinstance(a, integers) and not isinstance(a, bool))
        if kind == "bool":
            return lambda a: isinstance(a, (bool, np.bool_))
        return lambda a: True  # a tuple: numba's unboxing checks it
    dtype, ndarray = np.dtype(kind), np.ndarray
    if contiguous:
        return lambda a: (
            isinstance(a, ndarray) and a.ndim == rank and a.dtype == dtype
            and a.flags.c_contiguous
        )  # fmt: skip
    return lambda a: isinstance(a, ndarray) and a.ndim == rank and a.dtype == dtype


def _argument_types(signature: str) -> list[tuple[str, int, bool]]:
    """(numpy type, rank (0 a scalar), contiguous) of each argument of ``signature``."""
    depth, start = 0, len(signature) - 1
    for i in range(len(signature) - 1, -1, -1):  # the argument list: the last (...)
        depth += {")": 1, "(": -1}.get(signature[i], 0)
        if depth == 0:
            start = i
            break
    parts, depth, current = [], 0, ""
    for ch in signature[start + 1 : -1]:
        depth += {"(": 1, "[": 1, ")": -1, "]": -1}.get(ch, 0)
        if ch == "," and depth == 0:
            parts.append(current.strip())
            current = ""
        else:
            current += ch
    parts.append(current.strip())
    out = []
    for part in filter(None, parts):
        m = re.fullmatch(r"(\w+)(?:\[(.*)\])?", part)
        name, dims = (m.group(1), m.group(2)) if m else (part, None)
        kind = _DTYPES.get(name, name)
        if dims is None:
            out.append((kind, 0, False))
        else:
            axes = [d.strip() for d in dims.split(",")]
            out.append((kind, len(axes), axes[-1] == "::1"))
    return out


def _jit(fn: Callable[..., Any], *, inline: bool, cache: bool) -> Any:
    numba = _numba()
    options: dict[str, Any] = {"nogil": True, "error_model": "numpy"}
    if inline:
        options["inline"] = "always"
    if cache:
        try:
            return numba.njit(fn, cache=True, **options)
        except RuntimeError:  # numba: "cannot cache function ...: no locator available"
            pass
    return numba.njit(fn, **options)


@functools.cache
def _numba() -> ModuleType:
    """numba, its numpy support loaded with ``scipy.linalg.cython_blas`` unimportable for
    the moment of its BLAS check (nothing is hidden when scipy.linalg is loaded already)."""
    import numba

    blas = "scipy.linalg.cython_blas"
    if "numba.np.arraymath" in sys.modules or "scipy.linalg" in sys.modules:
        return numba
    sys.modules[blas] = None  # type: ignore[assignment]  # an import of it raises ImportError
    try:
        import numba.np.arraymath
    except ImportError:  # another numba's layout: it loads its own way at the first compile
        pass
    finally:
        del sys.modules[blas]
    return numba


def never_compiled(*functions: Any) -> bool:
    """Whether numba's disk cache lacks the machine code of one of ``functions`` (made with
    :func:`compiled` where numba's JIT compiles them): their first call will compile them
    (seconds each) rather than load them. False where numba cannot say (no cache, another
    numba's layout, a built group)."""
    for fn in functions:
        index = getattr(
            getattr(getattr(fn, "_cache", None), "_cache_file", None), "_index_path", None
        )
        if isinstance(index, str) and not os.path.exists(index):
            return True
    return False


def say_when_compiling(what: str, *functions: Any) -> None:
    """One line on a terminal before ``functions`` are compiled by numba's JIT for the first
    time on this machine (the first flight after an install sits half a minute in it
    otherwise); nothing where stderr is not a terminal (scripts, tests, workers' pipes) or
    the code is cached or built."""
    if never_compiled(*functions):
        compiled_build.say_compiling(what)
