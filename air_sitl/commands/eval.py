"""``air-sitl eval ARCHIVE --estimate SOURCE``: score position estimates against the truth.

Prints one screen (a column per estimate); ``--json`` writes the SPEC section 5 report (one
object, or a list for several estimates), ``--plots`` the figures, and ``--require`` turns the
run into a gate: exit 1 with one line per failed requirement (and one line per requirement
met when all hold).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from air_sitl.errors import OptionError

HELP = "score position estimates against an archive's truth (report, JSON, plots, CI gate)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``eval``."""
    parser.add_argument("archive", metavar="ARCHIVE", help="archive folder or .zip")
    parser.add_argument(
        "--estimate",
        metavar="SOURCE",
        action="append",
        required=True,
        help="estimates/NAME.csv of the archive by NAME, 'svo' (AIR's SvoX..Z), or a path to "
        "a CSV (the bus recorder's columns) or a TUM file 't x y z qx qy qz qw'; repeatable",
    )
    parser.add_argument(
        "--align",
        choices=("none", "posyaw", "se3", "sim3"),
        default="none",
        help="alignment before scoring: none (absolute localizers, default), posyaw (4-DoF, "
        "VIO), se3, sim3 (monocular VO; evo's Umeyama)",
    )
    parser.add_argument("--json", metavar="FILE", default=None, help="write the report as JSON")
    parser.add_argument("--plots", metavar="DIR", default=None, help="write PNG figures here")
    parser.add_argument(
        "--require",
        metavar="EXPR",
        action="append",
        default=[],
        help="a requirement like 'horizontal_error_m.rmse<=20' or 'recall.25m>=0.9' "
        "(dotted report key, <= < >= > ==); exit 1 if an estimate fails one; repeatable",
    )


def run(args: argparse.Namespace) -> int:
    """Score, print, write; 0 when every requirement holds, 1 otherwise."""
    from air_sitl.eval import score_sources
    from air_sitl.eval.report import table
    from air_sitl.eval.require import failures, met, parse

    requirements = [parse(text) for text in args.require]
    scored = score_sources(Path(args.archive), args.estimate, args.align)
    reports = [s.report for s in scored]
    failed = failures(requirements, reports)  # unknown keys are user errors: before writing
    sys.stdout.write(table(reports) + "\n")
    if args.json is not None:
        document = reports[0] if len(reports) == 1 else reports
        try:
            Path(args.json).write_text(
                json.dumps(document, indent=2, allow_nan=False) + "\n", encoding="utf-8"
            )
        except OSError as err:
            msg = f"{args.json}: cannot write: {err.strerror}"
            raise OptionError(msg) from None
    if args.plots is not None:
        from air_sitl.eval.plots import write_plots  # matplotlib (0.5 s) only for figures

        for path in write_plots(scored, Path(args.plots)):
            sys.stdout.write(f"{path}\n")
    for line in failed:
        sys.stderr.write(f"air-sitl: requirement failed: {line}\n")
    for line in [] if failed else met(requirements, reports):
        sys.stderr.write(f"air-sitl: requirement met: {line}\n")
    for source, report in zip(args.estimate, reports, strict=True):
        if source == "svo" and not report.get("estimated_frames"):
            sys.stderr.write(
                "air-sitl: note: svo: the archive's SvoX..SvoZ are empty: a simulated archive "
                "has them only when `fly --svo-columns NAME` filled them (score its "
                "estimates/NAME.csv with --estimate NAME)\n"
            )
    return 1 if failed else 0
