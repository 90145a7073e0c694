"""Baseline localizers behind one protocol (:mod:`air_sitl.localize.base`), run offline over an
archive (:func:`localize_archive`) or online on the zenoh bus by the same code.

    from air_sitl.localize import localize_archive
    path = localize_archive(Path("out/UL-200"), "vo")   # -> out/UL-200/estimates/vo.csv

Drivers: :mod:`~air_sitl.localize.archive` (offline: ``imu.csv``, the GNSS fix of the first
frame or outside recorded denial windows, seeded barometer and airspeed models from truth:
:mod:`~air_sitl.localize.inputs`) and :mod:`~air_sitl.localize.online` (the bus: ``imu``,
``gps``; no barometer or airspeed there). Both write, or have the bus recorder write,
``estimates/<name>.csv`` in one format (:mod:`~air_sitl.localize.output`). Command:
``air-sitl localize``. Speed and accuracy: ``benchmarks/bench_localize.py``.

Methods are registered in :data:`METHODS` (:mod:`~air_sitl.localize.methods`): name -> factory.
The drivers call the factory with no arguments (``METHODS[name]()``) and give everything a flight
provides (home, camera, map, reference map and date, seed, manifest) through
:class:`LocalizerContext` in ``reset``; keyword options are for callers tuning a method.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from air_sitl.localize.archive import run_archive
from air_sitl.localize.base import (
    Estimate,
    GnssFix,
    ImuReading,
    Localizer,
    LocalizerContext,
    Observation,
)
from air_sitl.localize.methods import METHODS


def localize_archive(archive: Path, method: str, **options: Any) -> Path:
    """Run ``method`` over an archive folder; write and return ``ARCHIVE/estimates/NAME.csv``.

    ``options`` are those of :func:`~air_sitl.localize.archive.run_archive` (``name``,
    ``reference_map``, ``reference_date``, ``seed`` ...).
    """
    return run_archive(Path(archive), method, **options).path


__all__ = [
    "METHODS",
    "Estimate",
    "GnssFix",
    "ImuReading",
    "Localizer",
    "LocalizerContext",
    "Observation",
    "localize_archive",
]
