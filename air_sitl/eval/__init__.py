"""Scoring of position estimates against an archive's truth (``air-sitl eval``, SPEC section 5).

    from air_sitl.eval import evaluate, evaluate_many
    report = evaluate(Path("out/UL-200"), "mine")              # estimates/mine.csv, unaligned
    reports = evaluate_many(Path("out/UC-200"), ["svo", "vo.tum"], align="sim3")

Maths without I/O in :mod:`~air_sitl.eval.trajectory` (matching and interpolation),
:mod:`~air_sitl.eval.align` (evo's Umeyama, 4-DoF position+yaw), :mod:`~air_sitl.eval.turns`,
:mod:`~air_sitl.eval.metrics`; the report in :mod:`~air_sitl.eval.report`; file formats in
:mod:`~air_sitl.eval.sources`; figures in :mod:`~air_sitl.eval.plots` (matplotlib, imported
only when asked for).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from air_sitl.dataset.reader import open_archive
from air_sitl.eval.align import ALIGNMENTS
from air_sitl.eval.errors import EvalError
from air_sitl.eval.report import Scored, score
from air_sitl.eval.sources import load_estimate, load_truth

__all__ = ["ALIGNMENTS", "EvalError", "Scored", "evaluate", "evaluate_many", "score_sources"]


def score_sources(archive: Path | str, sources: Sequence[str], align: str = "none") -> list[Scored]:
    """Every source scored against one archive, its truth read once (reports and arrays)."""

    if align not in ALIGNMENTS:
        msg = f"--align {align!r}: expected one of {', '.join(ALIGNMENTS)}"
        raise EvalError(msg)
    with open_archive(archive) as opened:
        truth = load_truth(opened)
        estimates = [load_estimate(opened, source) for source in sources]
    return [score(truth, est, align, archive=str(archive)) for est in estimates]


def evaluate_many(
    archive: Path | str, sources: Sequence[str], align: str = "none"
) -> list[dict[str, Any]]:
    """The SPEC report of each source, in order, sharing one truth load."""
    return [s.report for s in score_sources(archive, sources, align)]


def evaluate(archive: Path | str, source: str, align: str = "none") -> dict[str, Any]:
    """The SPEC section 5 report of one estimate source against an archive."""
    return evaluate_many(archive, [source], align)[0]
