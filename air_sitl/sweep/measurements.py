"""Per-entry measurements of a run, each saved as it finishes (what ``air-sitl bench`` keeps).

A run whose task names a measurements folder (``RunTask.measurements``: bench's ``reports/``)
saves, for each method or localizer it scores, ``<folder>/<scenario>/<entry>.json``: the eval
report (SPEC section 5), the archive it was scored against (identified by the SHA-256 of its
``frames.csv``, which no localizer touches), the localization wall time, and the per-frame
horizontal errors box plots need (``<entry>.errors.npy``). A file that exists, names the same
archive and holds no error is a finished measurement: the entry is not measured again, so an
interrupted bench resumes entry by entry.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from air_sitl.dataset.air_schema import FRAMES_CSV, MANIFEST_JSON
from air_sitl.files import write_json_atomic

F64 = npt.NDArray[np.float64]


@dataclass(frozen=True, slots=True, kw_only=True)
class EntryResult:
    """One (scenario, entry) measurement, or the one-line reason it failed."""

    scenario: str
    entry: str
    report: dict[str, Any] | None
    error: str | None = None
    localize_wall_s: float | None = None
    frames_per_s: float | None = None


def archive_id(archive: Path) -> str:
    """The identity of an archive's flight: the manifest's hash of ``frames.csv``."""
    manifest = json.loads((archive / MANIFEST_JSON).read_text(encoding="utf-8"))
    return str(manifest["files"][FRAMES_CSV])


def result_path(reports: Path, scenario: str, entry: str) -> Path:
    return reports / scenario / f"{entry}.json"


def save(reports: Path, result: EntryResult, archive: str, errors_m: F64 | None) -> None:
    """Write the errors first and the JSON last (its presence marks the measurement done)."""
    path = result_path(reports, result.scenario, result.entry)
    path.parent.mkdir(parents=True, exist_ok=True)
    if errors_m is not None:
        tmp = path.with_name(path.stem + ".errors.tmp.npy")
        np.save(tmp, errors_m.astype(np.float32))
        tmp.replace(path.with_name(path.stem + ".errors.npy"))
    content = {
        "scenario": result.scenario,
        "entry": result.entry,
        "archive_id": archive,
        "error": result.error,
        "localize_wall_s": result.localize_wall_s,
        "frames_per_s": result.frames_per_s,
        "report": result.report,
    }
    write_json_atomic(path, content)


def read(reports: Path, scenario: str, entry: str, archive: str) -> EntryResult | None:
    """What was measured of this archive, failures included; None when nothing was (or
    another flight was)."""
    path = result_path(reports, scenario, entry)
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(content, dict) or content.get("archive_id") != archive:
        return None
    return EntryResult(
        scenario=scenario,
        entry=entry,
        report=content.get("report"),
        error=content.get("error"),
        localize_wall_s=content.get("localize_wall_s"),
        frames_per_s=content.get("frames_per_s"),
    )


def load(reports: Path, scenario: str, entry: str, archive: str) -> EntryResult | None:
    """A finished measurement of this archive, or None (missing, failed, or another flight):
    failures are tried again."""
    result = read(reports, scenario, entry, archive)
    return None if result is None or result.error is not None else result


def load_errors(reports: Path, scenario: str, entry: str) -> F64 | None:
    """The per-frame horizontal errors saved with a measurement (None when absent)."""
    path = result_path(reports, scenario, entry).with_name(f"{entry}.errors.npy")
    if not path.is_file():
        return None
    errors: F64 = np.load(path).astype(np.float64)
    return errors
