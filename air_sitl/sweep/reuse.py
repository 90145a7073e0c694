"""Methods that read no imagery, localized and scored once per flight (issue 34).

A method that declares ``reads_imagery = False`` (:func:`~air_sitl.localize.methods.
reads_imagery`: ``deadreckon``) is given the same inputs by every map date of one flight
(the archives' ``frames.csv``, ``imu.csv``, ``metadata.csv``, home and camera:
:func:`~air_sitl.localize.archive.imagery_free_inputs`), so its estimates and their scores
are the same for each date. A worker keeps the last :data:`KEPT` such results; a run over
another date of the same flight writes the kept estimates into its own archive
(``estimates/<name>.csv`` and the manifest's entry: the bytes of computing them) and takes
the kept score, its report naming this run's archive. Keys hold the method, the inputs'
identity, the seed and the reference date, and the score's alignment: anything else and
the method runs again.
"""

from __future__ import annotations

import copy
import json
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from air_sitl.dataset.air_schema import MANIFEST_JSON
from air_sitl.dataset.manifest import manifest_home
from air_sitl.eval import Scored
from air_sitl.localize.archive import LocalizeRun, imagery_free_inputs
from air_sitl.localize.methods import reads_imagery
from air_sitl.localize.output import write_estimates

KEPT = 8  # results a worker keeps (a sweep's groups of map dates come one after another)

Key = tuple[Any, ...]


@dataclass(frozen=True, slots=True)
class Kept:
    """A method's run over one date of a flight, and its scores by alignment."""

    run: LocalizeRun
    home: Any  # the archive's home (GeoPoint), what the estimates file is written against
    scored: dict[str, Scored]


_KEPT: OrderedDict[Key, Kept] = OrderedDict()


def key_of(archive: Path, method: str, *, seed: int, reference_date: int | None) -> Key | None:
    """The key of ``method``'s result over ``archive``; None when it reads imagery (or the
    archive's inputs cannot be identified): it runs every time."""
    if reads_imagery(method):
        return None
    inputs = imagery_free_inputs(archive)
    return None if inputs is None else (method, inputs, seed, reference_date)


def recall(
    archive: Path, methods: Sequence[str], *, seed: int, reference_date: int | None
) -> tuple[dict[str, Key | None], dict[str, LocalizeRun | str]]:
    """Each method's key, and the runs of those kept from another date of the flight,
    written into ``archive`` (:func:`reuse_run`); the others are the caller's to run."""
    keys = {m: key_of(archive, m, seed=seed, reference_date=reference_date) for m in methods}
    runs: dict[str, LocalizeRun | str] = {}
    for method, key in keys.items():
        if (run := reuse_run(key, archive)) is not None:
            runs[method] = run
    return keys, runs


def remembered(
    keys: dict[str, Key | None], archive: Path, runs: dict[str, LocalizeRun | str]
) -> dict[str, LocalizeRun | str]:
    """``runs`` (just computed over ``archive``: each a run, or why it failed), the runs of
    methods with a key kept (:func:`remember`)."""
    for method, run in runs.items():
        if isinstance(run, LocalizeRun):
            remember(keys.get(method), run, archive)
    return runs


def remember(key: Key | None, run: LocalizeRun, archive: Path) -> None:
    """Keep ``run`` (just computed over ``archive``) for the flight's other dates."""
    if key is None:
        return
    manifest = json.loads((archive / MANIFEST_JSON).read_text(encoding="utf-8"))
    _KEPT[key] = Kept(run=run, home=manifest_home(manifest), scored={})
    _KEPT.move_to_end(key)
    while len(_KEPT) > KEPT:
        _KEPT.popitem(last=False)


def reuse_run(key: Key | None, archive: Path) -> LocalizeRun | None:
    """The kept run of ``key`` written into ``archive`` (its estimates file and manifest
    entry, as computing it writes them), or None when none is kept."""
    kept = None if key is None else _KEPT.get(key)
    if kept is None:
        return None
    path = write_estimates(archive, kept.run.name, kept.run.estimates, kept.home)
    return replace(kept.run, path=path)


def score(key: Key | None, align: str, compute: Callable[[], Scored]) -> Scored:
    """The score kept under ``key`` and ``align`` (eval's alignment), else ``compute()``'s,
    kept when ``key`` is: a copy of a kept one (its report the caller's to change)."""
    kept = None if key is None else _KEPT.get(key)
    if kept is None:
        return compute()
    if align not in kept.scored:
        kept.scored[align] = compute()
    scored = kept.scored[align]
    return replace(scored, report=copy.deepcopy(scored.report))


def forget() -> None:
    """Drop every kept result (tests)."""
    _KEPT.clear()
