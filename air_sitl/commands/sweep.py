"""``air-sitl sweep SPEC.yaml --out DIR [-j N | --ray [ADDRESS]]``; ``air-sitl sweep report DIR``.

A sweep flies every run of a SPEC (the product of its axes, plus explicit runs), localizes and
scores each with the SPEC's methods and localizers, and appends one row per run to
``DIR/results.jsonl``; run folders go under ``DIR/runs/ID/``. Runs already in results.jsonl
are skipped with ``--resume``; a failed run records its one-line error and the others go on; Ctrl-C
stops cleanly. ``report`` writes ``DIR/report.md`` and ``DIR/report.png``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from air_sitl.errors import OptionError
from air_sitl.options import int_in_range
from air_sitl.outdir import add_out_arguments

HELP = "many runs from one SPEC (axes x seeds): fly, localize, eval; on a process pool or Ray"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``sweep``."""
    parser.add_argument(
        "spec", metavar="SPEC", help="the sweep's YAML SPEC, or 'report' to report on DIR"
    )
    parser.add_argument("dir", nargs="?", metavar="DIR", help="sweep folder (with 'report')")
    parser.add_argument("--out", default=None, metavar="DIR", help="sweep folder (created)")
    add_executor_arguments(parser)
    parser.add_argument(
        "--keep",
        choices=("all", "frames", "none"),
        default="all",
        help="what stays of each run's archive: all (default); frames: the per-frame tables, "
        "estimates and summaries, no JPEG images; none: estimates and summary.json only",
    )
    parser.add_argument(
        "--retry-failed",
        action="store_true",
        help="continue the sweep in --out (as --resume) and run again the runs recorded as failed",
    )
    add_out_arguments(
        parser, resume="continue the sweep in --out (same SPEC): runs with a row are skipped"
    )
    parser.add_argument(
        "--missions", default=None, metavar="DIR", help="folder of the plans 'scenario' names"
    )
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


def add_executor_arguments(parser: argparse.ArgumentParser, *, note: str = "") -> None:
    """``-j N`` or ``--ray [ADDRESS]``: where the runs execute (sweep, and bench its preset)."""
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "-j", "--jobs", default="1", metavar="N", help="worker processes (default 1)"
    )
    where.add_argument(
        "--ray",
        nargs="?",
        const="",
        default=None,
        metavar="ADDRESS",
        help="run on Ray: alone, a local Ray; with ADDRESS (auto, HOST:6379, ray://HOST:10001), "
        f"that cluster (pip install 'air-sitl[ray]'){note}",
    )


def run(args: argparse.Namespace) -> int:
    """Sweep (exit 0: every run of the SPEC succeeded, 1: some failed, 130: interrupted)."""
    if args.spec == "report" and not Path("report").is_file():
        return _report(args)
    if args.dir is not None:
        msg = f"sweep {args.spec}: unexpected {args.dir!r} (the folder goes in --out DIR)"
        raise OptionError(msg)
    if args.out is None:
        msg = "sweep: --out DIR is required (where results.jsonl and the runs go)"
        raise OptionError(msg)
    from air_sitl.dataset.scenarios import missions_dir
    from air_sitl.outdir import claim_folder
    from air_sitl.sweep import (
        PoolExecutor,
        RayExecutor,
        load_spec,
        print_outcome,
        resume_problem,
        run_sweep,
    )

    missions = None
    if args.missions is not None:
        missions = missions_dir(args.missions)
    spec = load_spec(Path(args.spec), missions=missions)
    jobs = int_in_range("-j", args.jobs, 1, 256)
    executor = PoolExecutor(jobs) if args.ray is None else RayExecutor(args.ray or None)
    out = Path(args.out)
    if args.overwrite and args.retry_failed:
        msg = "--retry-failed continues a sweep; --overwrite replaces it: choose one"
        raise OptionError(msg)
    claim_folder(
        out,
        overwrite=args.overwrite,
        resume=args.resume or args.retry_failed,
        resume_problem=lambda: resume_problem(spec, out, args.keep),
    )
    outcome = run_sweep(
        spec,
        out,
        executor,
        keep=args.keep,
        retry_failed=args.retry_failed,
        stream=None if args.quiet else sys.stderr,
    )
    if not args.quiet or outcome.interrupted:
        print_outcome(outcome, out, sys.stderr)
    if outcome.interrupted:
        return 130
    return 1 if outcome.failed_total else 0


def _report(args: argparse.Namespace) -> int:
    if args.dir is None:
        msg = "sweep report: give the sweep folder: air-sitl sweep report DIR"
        raise OptionError(msg)
    from air_sitl.sweep.report import coverage_notes, write_report

    written = write_report(Path(args.dir))
    if not args.quiet:
        for note in coverage_notes(Path(args.dir)):
            print(f"sweep report: {note}", file=sys.stderr)
        for path in written:
            print(path)
    return 0
