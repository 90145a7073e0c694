"""``manifest.json``: what an archive holds, a SHA-256 per file, and ``complete: true`` last.

Every file of an archive is byte-identical across runs with the same inputs and seed, except
``summary.json`` (it holds wall-clock figures) and the logs of external estimators under
``estimates/`` (their latency in wall milliseconds); the manifest names them in
``wall_clock_files`` so that determinism comparisons can leave them out.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from air_sitl.dataset.air_schema import (
    ESTIMATES_DIR,
    MANIFEST_JSON,
    RECORDING_JSON,
    SUMMARY_JSON,
)
from air_sitl.errors import DatasetError
from air_sitl.files import TMP_SUFFIX, parse_json_object, sha256_file, write_json_atomic
from air_sitl.state import GeoPoint

MANIFEST_FORMAT = "air-sitl-archive"
MANIFEST_VERSION = 1
WALL_CLOCK_FILES = (SUMMARY_JSON,)


def sha256_bytes(data: bytes) -> str:
    """Hex SHA-256 of ``data``."""
    return hashlib.sha256(data).hexdigest()


def archive_files(folder: Path) -> list[str]:
    """Every file of an archive that the manifest lists, as sorted POSIX relative paths.

    Leaves out the manifest itself, hidden files (the in-progress marker) and temporary files.
    """
    names: list[str] = []
    for path in folder.rglob("*"):
        rel = path.relative_to(folder)
        if any(part.startswith(".") for part in rel.parts):
            continue
        if not path.is_file() or path.name.endswith(TMP_SUFFIX):
            continue
        text = rel.as_posix()
        if text in (MANIFEST_JSON, RECORDING_JSON):
            continue
        names.append(text)
    return sorted(names)


def hash_files(folder: Path, known: Mapping[str, str] | None = None) -> dict[str, str]:
    """SHA-256 of every archive file; ``known`` supplies hashes computed while writing."""
    known = known or {}
    out: dict[str, str] = {}
    for name in archive_files(folder):
        digest = known.get(name)
        out[name] = digest if digest is not None else sha256_file(folder / name)
    return out


def write_manifest(
    folder: Path, info: Mapping[str, Any], files: Mapping[str, str]
) -> dict[str, Any]:
    """Write ``manifest.json`` atomically, with ``complete: true`` as its last key."""
    content: dict[str, Any] = {"format": MANIFEST_FORMAT, "format_version": MANIFEST_VERSION}
    content.update(info)
    content["wall_clock_files"] = [
        f for f in sorted(files) if f in WALL_CLOCK_FILES or f.startswith(ESTIMATES_DIR + "/")
    ]
    content["files"] = dict(sorted(files.items()))
    content["complete"] = True
    write_json_atomic(folder / MANIFEST_JSON, content)
    return content


def read_manifest(folder: Path) -> dict[str, Any] | None:
    """The manifest of a folder archive, None when there is none (unfinished or original AIR)."""
    path = folder / MANIFEST_JSON
    if not path.exists():
        return None
    try:
        data = path.read_bytes()
    except OSError as err:
        msg = f"{path}: cannot read the manifest: {err.strerror}"
        raise DatasetError(msg) from None
    return parse_json_object(data, str(path), DatasetError)


def manifest_home(manifest: Mapping[str, Any] | None) -> GeoPoint | None:
    """The archive's home (``"home"``), None when there is none or it is not three numbers."""
    home: Any = (manifest or {}).get("home")
    try:
        return GeoPoint(**{k: float(home[k]) for k in ("lat_deg", "lon_deg", "alt_amsl_m")})
    except (KeyError, TypeError, ValueError):
        return None


def refresh_manifest(folder: Path, changed: Mapping[str, str] | None = None) -> None:
    """Re-hash files added or changed after the manifest was written (estimates, SvoX..Z).

    Files whose hash is in ``changed`` are taken from there; files already listed keep their
    hash unless changed; new files are hashed from disk. Does nothing without a manifest.
    """
    manifest = read_manifest(folder)
    if manifest is None:
        return
    old = manifest.get("files", {})
    known = {k: v for k, v in old.items() if isinstance(v, str)}
    known.update(changed or {})
    files = hash_files(folder, known)
    info = {
        k: v
        for k, v in manifest.items()
        if k not in ("format", "format_version", "wall_clock_files", "files", "complete")
    }
    write_manifest(folder, info, files)
