"""Built kernels (:mod:`air_sitl.compiled`): where a group's extension module is kept, how
the first process to need it builds it while the others wait, and the build itself
(``python -m air_sitl.compiled_build PATH MODULE...``, numba's ahead-of-time compiler).

The builds are kept in the package's ``__pycache__`` where writable, else in the
user's cache directory (``AIR_SITL_CACHE_DIR`` overrides both), named by a hash of the
group's source (with the air_sitl modules it imports from: the constants it takes), of
``compiled.py`` and this module, of the numba, llvmlite, numpy and Python versions and of
the CPU (the code is compiled for it with its features, as numba's JIT does). A process that
finds it missing takes a lock on a file beside it (other processes wait there), builds it in
a child process, written under a temporary name and renamed (no process ever loads a part of
it), removes the builds of other versions there, and loads it. Where it cannot (no C
compiler or no Python headers, numba without ``pycc`` or setuptools, no writable place) it
returns None: numba's JIT then, as before. A build that fails leaves its output in a
``.failed`` file beside it and is not tried again for that version.

The builder imports the group's modules with ``AIR_SITL_BUILDING`` set: their kernels are
numba's (not cached: each one the exported kernels call is compiled here, by this numba)
and carry their signature; pycc compiles each exported one with the JIT's options (IEEE
division, the GIL released during a call, no fastmath) for this CPU with its features: the
same machine arithmetic as the JIT's, so the same bytes.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import importlib.util
import inspect
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

PACKAGE = Path(__file__).resolve().parent
BUILDING = "AIR_SITL_BUILDING"  # set in the builder: kernels are numba's, with signatures
MODULE = "_air_sitl_kernels"  # every group's extension module's name (they share C objects)


def symbol(module: str, name: str) -> str:
    """The name of kernel ``name`` of ``module`` in its group's extension module."""
    return f"{module.rsplit('.', 1)[-1]}__{name}"


@functools.cache
def machine_code(group: str, modules: tuple[str, ...], what: str) -> ModuleType | None:
    """The extension module of ``modules``' kernels, built now if it is not yet (waiting for
    another process building it); None where it cannot be."""
    name = build_name(group, modules)
    places = cache_dirs()
    for place in places:
        if (place / name).exists():
            return _load(place / name)
    writable = next((p for p in places if _writable(p)), None)
    if writable is None or not _can_build():
        return None
    return _build(writable / name, modules, what)


def build_name(group: str, modules: tuple[str, ...]) -> str:
    """The file name of a group's build for this source, these versions and this CPU."""
    h = hashlib.sha256()
    for path in sorted(_sources(modules)):
        h.update(path.name.encode() + b"\0" + path.read_bytes() + b"\0")
    h.update(_toolchain().encode())
    suffix = ".pyd" if sys.platform == "win32" else ".so"
    return f"_air_sitl_{group}-{h.hexdigest()[:20]}{suffix}"


def cache_dirs() -> list[Path]:
    """Where builds are looked for, then made, in order."""
    override = os.environ.get("AIR_SITL_CACHE_DIR")
    if override:
        return [Path(override)]
    if sys.platform == "win32":
        user = Path(os.environ.get("LOCALAPPDATA", Path.home())) / "air-sitl" / "Cache"
    else:
        user = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "air-sitl"
    return [PACKAGE / "__pycache__", user]


def _sources(modules: tuple[str, ...]) -> set[Path]:
    paths = {PACKAGE / "compiled.py", PACKAGE / "compiled_build.py"}
    for module in modules:
        path = _module_path(module)
        paths.add(path)
        imported = re.findall(r"^from (air_sitl(?:\.\w+)*) import", path.read_text(), re.M)
        paths.update(_module_path(m) for m in imported)
    return paths


def _module_path(module: str) -> Path:
    base = PACKAGE.parent.joinpath(*module.split("."))
    return base.with_suffix(".py") if base.with_suffix(".py").exists() else base / "__init__.py"


def _toolchain() -> str:
    """The versions and the CPU the machine code depends on (numba not imported)."""
    parts = [sys.version, sys.platform, platform.machine(), _cpu()]
    for package in ("numba", "llvmlite"):
        version = _package_dir(package) / "_version.py"
        parts.append(version.read_text() if version.exists() else "-")
    import numpy

    parts.append(numpy.__version__)
    return "\n".join(parts)


def _toolchain_hash() -> str:
    return hashlib.sha256(_toolchain().encode()).hexdigest()[:20]


def _package_dir(name: str) -> Path:
    """Where the package ``name`` is, found without importing it (a missing path if not)."""
    spec = importlib.util.find_spec(name)
    where = list(spec.submodule_search_locations or []) if spec is not None else []
    return Path(where[0]) if where else PACKAGE / "missing" / name


def _cpu() -> str:
    """The CPU model and its features (Linux: /proc/cpuinfo's first processor)."""
    keys = {"vendor_id", "cpu family", "model", "model name", "stepping", "flags", "Features",
            "CPU implementer", "CPU architecture", "CPU variant", "CPU part"}  # fmt: skip
    try:
        text = Path("/proc/cpuinfo").read_text().split("\n\n")[0]
    except OSError:
        return platform.machine()
    return "\n".join(line for line in text.splitlines() if line.split(":")[0].strip() in keys)


def _writable(place: Path) -> bool:
    try:
        place.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    return os.access(place, os.W_OK)


def _can_build() -> bool:
    """A C compiler, Python's headers, numba's ahead-of-time compiler and setuptools (which
    it uses) are there."""
    import sysconfig

    cc = (sysconfig.get_config_var("CC") or "cc").split()
    if sys.platform != "win32" and (not cc or shutil.which(cc[0]) is None):
        return False
    headers = Path(sysconfig.get_paths()["include"]) / "Python.h"
    pycc = _package_dir("numba") / "pycc" / "__init__.py"
    setuptools = importlib.util.find_spec("setuptools") is not None
    return headers.exists() and pycc.exists() and setuptools


def _build(path: Path, modules: tuple[str, ...], what: str) -> ModuleType | None:
    """Build ``path`` unless another process has (holding a lock meanwhile), and load it."""
    failed = path.with_suffix(".failed")
    group = path.name.split("-")[0]
    with _Locked(path.with_name(f"{group}.lock")):
        if not path.exists() and not failed.exists():
            say_compiling(what)
            env = dict(os.environ)
            env["PYTHONPATH"] = os.pathsep.join(
                [str(PACKAGE.parent), *filter(None, [env.get("PYTHONPATH")])]
            )
            run = subprocess.run(
                [sys.executable, "-m", "air_sitl.compiled_build", str(path), *modules],
                capture_output=True, text=True, env=env, check=False,
            )  # fmt: skip
            if run.returncode > 0:  # not killed by a signal: noted, not tried again
                failed.write_text(run.stdout + run.stderr)
                _tell(f"air-sitl: could not compile {what} ({failed}): numba's JIT instead")
            _prune(path)
    return _load(path) if path.exists() else None


def _prune(path: Path) -> None:
    """Remove the builds of other versions of ``path``'s group, and C runtimes of other
    toolchains, beside it."""
    group = path.name.split("-")[0]
    mixins = f"_air_sitl_mixins-{_toolchain_hash()}"
    for old in path.parent.glob(f"{group}-*"):
        if old.stem != path.stem:
            old.unlink(missing_ok=True)
    for old in path.parent.glob("_air_sitl_mixins-*"):
        if old.name != mixins:
            shutil.rmtree(old, ignore_errors=True)


class _Locked:
    """An exclusive lock on a file for a ``with`` block (POSIX; elsewhere none: the build is
    then written aside and renamed, the last rename wins)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.fd = -1

    def __enter__(self) -> None:
        try:
            import fcntl
        except ImportError:
            return
        self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX)
        except OSError:  # a file system without locks
            os.close(self.fd)
            self.fd = -1

    def __exit__(self, *exc: object) -> None:
        if self.fd >= 0:
            os.close(self.fd)  # releases the lock


def _load(path: Path) -> ModuleType | None:
    """The extension module at ``path``; None where it does not load."""
    spec = importlib.util.spec_from_file_location(MODULE, path)
    if spec is None or spec.loader is None:
        return None
    try:
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
    except ImportError:
        return None
    return module


def say_compiling(what: str) -> None:
    """The line a terminal gets before kernels are compiled for the first time."""
    _tell(
        f"air-sitl: compiling {what} for this machine, once (about half a minute; later runs "
        "load it)"
    )


def _tell(line: str) -> None:
    if sys.stderr.isatty():
        print(line, file=sys.stderr, flush=True)


# --- the build (in its own process) ---------------------------------------------------------


def build(path: Path, modules: list[str]) -> None:
    """Compile the exported kernels of ``modules`` into the extension module ``path``."""
    os.environ[BUILDING] = "1"
    entries = []
    for name in modules:
        module = importlib.import_module(name)
        for value in vars(module).values():
            signature = getattr(value, "exported_signature", None)
            if signature is not None and getattr(value, "__module__", None) == name:
                entries.append((symbol(name, value.py_func.__name__), signature, _entry(value)))
    if not entries:
        raise SystemExit(f"air-sitl: {' '.join(modules)}: no kernel with a signature to build")
    cc = _compiler(path)
    for name, signature, fn in sorted(entries):
        cc.export(name, signature)(fn)
    fd, temp = tempfile.mkstemp(prefix=f".{path.stem}-", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        cc.output_dir = str(path.parent)
        cc.output_file = Path(temp).name
        cc.compile()
        os.chmod(temp, 0o755)
        os.replace(temp, path)
    finally:
        if os.path.exists(temp):
            os.unlink(temp)


def _compiler(path: Path) -> Any:
    """numba's ahead-of-time compiler (untyped: Any) set as the JIT: ``compiled._jit``'s
    options, this CPU with its features; and pycc's C runtime compiled once per toolchain."""
    pycc: Any = importlib.import_module("numba.pycc.compiler")
    codegen: Any = importlib.import_module("numba.core.codegen")
    compile_extra = pycc.compile_extra

    def compile_as_jit(
        typing: Any, target: Any, fn: Any, args: Any, result: Any, flags: Any, **kwargs: Any
    ) -> Any:
        """pycc's compile of an exported function, with the JIT's flags and a fresh copy of
        them for each (a compile may change the flags it is given: inlining turns SSA off;
        pycc gives one object to all)."""
        flags = flags.copy()
        flags.error_model = "numpy"
        flags.release_gil = True
        return compile_extra(typing, target, fn, args, result, flags, **kwargs)

    def host_features(self: Any) -> str:
        return str(self._get_host_cpu_features())

    pycc.compile_extra = compile_as_jit
    codegen.AOTCPUCodegen._customize_tm_features = host_features  # as JITCPUCodegen's
    cc = importlib.import_module("numba.pycc").CC(MODULE)
    cc.target_cpu = "host"
    compile_mixins = cc._compile_mixins

    def shared_mixins(build_dir: str) -> list[str]:
        """pycc's C runtime (the same for every group: one module name), compiled by the
        first build of this toolchain and kept beside the builds (renamed in complete)."""
        kept = path.parent / f"_air_sitl_mixins-{_toolchain_hash()}"
        with _Locked(path.with_name("_air_sitl_mixins.lock")):  # builds of other groups wait
            if not kept.is_dir():
                temp = Path(tempfile.mkdtemp(prefix=".mixins-", dir=path.parent))
                temp.chmod(0o755)
                for k, obj in enumerate(compile_mixins(build_dir)):
                    shutil.copy(obj, temp / f"{k}-{Path(obj).name}")
                temp.rename(kept)
        return sorted(str(obj) for obj in kept.iterdir())

    cc._compile_mixins = shared_mixins
    return cc


def _entry(kernel: Any) -> Any:
    """A function that calls ``kernel`` (a numba dispatcher) with its arguments: exported in
    its place, it has numba compile the kernel once, as its JIT does (with the kernel's own
    options), for the exported signature and for the kernels calling it alike (pycc would
    compile an exported function apart, a second time, with its own flags)."""
    names = ", ".join(inspect.signature(kernel.py_func).parameters)
    scope = {"kernel": kernel}
    exec(f"def entry({names}):\n    return kernel({names})\n", scope)
    return scope["entry"]


if __name__ == "__main__":
    build(Path(sys.argv[1]), sys.argv[2:])
