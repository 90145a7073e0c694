"""Atomic file writes (a temporary name beside the target, then a rename), UTF-8 text and JSON
objects and YAML mappings read back, a file's SHA-256, deterministic zips.

A reader (or a crash) never sees half a file: the target holds the old content or the new one.
Every writer of an archive file (JPEG frames, camera.yaml, summary and manifest JSON, the
rewritten ``metadata.csv``) goes through here; so does packing an archive as a zip.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import tempfile
import zipfile
from pathlib import Path
from typing import Any

import yaml

from air_sitl.errors import AirSitlError, DatasetError

TMP_SUFFIX = ".tmp"  # the temporary name of a file being written: <name>.tmp


def write_error(path: str | os.PathLike[str], err: OSError) -> DatasetError:
    """The one-line error of a failed write of ``path``."""
    return DatasetError(f"{os.fspath(path)}: cannot write: {err.strerror or err}")


def require_writable_folder(folder: Path, what: str, *, create: bool = True) -> None:
    """Check a file can be written in ``folder`` (created if need be; with ``create=False`` the
    check is made in its nearest existing parent and nothing is created); DatasetError with
    one line naming it (a read-only file system, no permission) before anything runs."""
    probe = folder
    if not create:
        while not probe.exists() and probe != probe.parent:
            probe = probe.parent
    try:
        if create:
            folder.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=probe, prefix=".air-sitl-probe-"):
            pass
    except OSError as err:
        msg = f"{folder}: cannot write in the {what}: {err.strerror or err}"
        raise DatasetError(msg) from None


def write_all(fd: int, data: bytes) -> None:
    """``os.write`` until every byte of ``data`` is written (short writes happen)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes, *, fsync: bool = False) -> None:
    """Write ``data`` to ``<path>.tmp`` and rename it to ``path`` (DatasetError on failure).

    ``fsync`` forces the bytes to disk before the rename. The temporary name never stays.
    """
    final = os.fspath(path)
    tmp = final + TMP_SUFFIX
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        try:
            write_all(fd, data)
            if fsync:
                os.fsync(fd)
        finally:
            os.close(fd)
        os.replace(tmp, final)
    except OSError as err:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise write_error(final, err) from None


def decode_text(data: bytes, where: str, error: type[AirSitlError]) -> str:
    """UTF-8 text (a BOM dropped); ``error`` naming ``where`` when ``data`` is not UTF-8."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as err:
        raise error(f"{where}: not UTF-8 text ({err})") from None


def parse_json_object(data: bytes | str, where: str, error: type[AirSitlError]) -> dict[str, Any]:
    """One JSON object; ``error`` naming ``where`` when ``data`` is not one."""
    try:
        value = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as err:
        msg = f"{where}: not a JSON object ({err})"
        raise error(msg) from None
    return _mapping(value, "a JSON object", where, error)


def parse_yaml_mapping(text: str, where: str, error: type[AirSitlError]) -> dict[str, Any]:
    """One YAML mapping; ``error`` naming ``where`` when ``text`` is not one."""
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as err:
        msg = f"{where}: not YAML ({err})"
        raise error(msg) from None
    return _mapping(value, "a mapping", where, error)


def _mapping(value: Any, kind: str, where: str, error: type[AirSitlError]) -> dict[str, Any]:
    """``value`` when it is a mapping; ``error`` naming ``where`` and what it is instead."""
    if not isinstance(value, dict):
        msg = f"{where}: expected {kind}, got {type(value).__name__}"
        raise error(msg)
    return value


def write_json_atomic(path: Path, content: Any) -> None:
    """Write ``content`` as indented JSON, synced to disk, atomically (DatasetError on failure)."""
    write_bytes_atomic(path, (json.dumps(content, indent=2) + "\n").encode("utf-8"), fsync=True)


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with path.open("rb") as f:
        while block := f.read(1 << 20):
            h.update(block)
    return h.hexdigest()


def zip_folder(folder: Path, out: Path) -> None:
    """Pack ``folder`` as ``out`` (stored, fixed timestamps: the same bytes every time)."""
    tmp = out.with_name(out.name + TMP_SUFFIX)
    files = sorted(p for p in folder.rglob("*") if p.is_file() and not p.name.startswith("."))
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_STORED) as zf:
        for path in files:
            info = zipfile.ZipInfo(
                f"{folder.name}/{path.relative_to(folder).as_posix()}", (1980, 1, 1, 0, 0, 0)
            )
            info.external_attr = 0o644 << 16
            info.compress_type = zipfile.ZIP_STORED
            with path.open("rb") as src, zf.open(info, "w") as dst:
                while block := src.read(1 << 20):
                    dst.write(block)
    tmp.replace(out)
