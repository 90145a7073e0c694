"""``air-sitl bench``: localization methods x AIR scenarios -> a leaderboard.

Makes (or reuses) the archives over the flight date, then sweeps them (a preset of ``air-sitl
sweep``: one run per scenario, on ``-j N`` processes or ``--ray``) running each built-in method
offline and each external localizer command on the bus in lockstep, scores everything with
``eval`` and writes ``DIR/leaderboard.md``, ``DIR/leaderboard.json`` and
``DIR/error_boxes.png``. An interrupted bench continues
from what it had measured with ``--resume``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.bus.args import DEFAULT_WAIT_TIMEOUT_S
from air_sitl.commands.sweep import add_executor_arguments
from air_sitl.errors import OptionError
from air_sitl.options import int_in_range, positive_number
from air_sitl.outdir import add_out_arguments

if TYPE_CHECKING:
    from air_sitl.bench import BenchConfig

HELP = "rank localization methods over the scenarios (AIR's and farmland): leaderboard, box plots"

# What --help shows without loading the methods and the bench (numpy, OpenCV, zenoh, JSBSim);
# tests/test_cli_startup.py keeps them equal to air_sitl.localize.METHODS, eval's ALIGNMENTS
# and air_sitl.bench.config's FLIGHT_DATES and REFERENCE_DATE.
METHOD_NAMES = ("deadreckon", "vo", "mapmatch", "mapmatch-axial", "fused")
ALIGNMENTS = ("none", "posyaw", "se3", "sim3")
FLIGHT_DATES = (0, 1, 2)
REFERENCE_DATE = 0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``bench``."""
    parser.add_argument(
        "--scenarios",
        default="all",
        help="'all' (default: AIR's 12 and the 6 farmland ones), 'air', 'farmland' or names "
        "such as UL-200,UC-300,AC-200",
    )
    parser.add_argument(
        "--methods",
        default="all",
        help=f"built-in methods, comma-separated: {', '.join(METHOD_NAMES)} (default all)",
    )
    parser.add_argument(
        "--localizer",
        metavar="NAME=COMMAND",
        action="append",
        default=[],
        help="an external localizer program, run on the bus in lockstep per scenario; it gets "
        "'--zenoh-connect ENDPOINT' appended (or {endpoint} replaced) and must publish "
        "estimate/NAME; repeatable",
    )
    parser.add_argument(
        "--wait-timeout",
        default=None,
        metavar="S",
        help="wall seconds each lockstep flight waits for an external localizer's subscriber "
        f"or estimate before giving up (fly's --wait-timeout, default {DEFAULT_WAIT_TIMEOUT_S:g})",
    )
    parser.add_argument("--out", metavar="DIR", required=True, help="bench folder")
    add_executor_arguments(parser, note="; the bench folder at the same path on every node")
    parser.add_argument("--missions", default=None, help="folder of the scenario plans")
    parser.add_argument(
        "--map",
        default=None,
        metavar="MAP",
        help="map every scenario flies over (dataset's --map): a folder of dated GeoTIFFs "
        "(map fetch's), dates a.tif,b.tif or a procedural map; --map-date and "
        "--reference-date are then indices of its dates (default: by the plan name)",
    )
    parser.add_argument(
        "--map-date",
        default=",".join(map(str, FLIGHT_DATES)),
        help="map dates the flights are rendered at, comma-separated (default "
        f"{','.join(map(str, FLIGHT_DATES))}): one bench per date in DIR/date<N>/ and "
        "DIR/leaderboard.md with a column per date gap; one date, such as 1, benches it alone "
        "in DIR",
    )
    parser.add_argument(
        "--reference-date",
        default=str(REFERENCE_DATE),
        help=f"map date map-matching methods match against (default {REFERENCE_DATE})",
    )
    parser.add_argument(
        "--align", choices=ALIGNMENTS, default="none", help="eval alignment (default none)"
    )
    parser.add_argument("--seed", default="0", help="flight and sensor seed (default 0)")
    parser.add_argument("--quiet", action="store_true", help="no progress, only the table")
    add_out_arguments(
        parser,
        resume="continue an interrupted bench in --out (same options): what was measured is kept",
    )


def config_from_args(args: argparse.Namespace) -> BenchConfig:
    """Validate every option before anything flies."""
    from air_sitl.bench import BenchConfig, parse_localizer, parse_methods
    from air_sitl.dataset.scenarios import missions_dir, parse_scenarios
    from air_sitl.localize import METHODS

    folder = missions_dir(args.missions)
    localizers = tuple(parse_localizer(text) for text in args.localizer)
    methods = parse_methods(args.methods, tuple(METHODS))
    names = [loc.name for loc in localizers]
    clash = sorted({n for n in names if names.count(n) > 1 or n in methods})
    if clash:
        msg = f"--localizer {clash[0]}: the name is used twice (methods and localizers share names)"
        raise OptionError(msg)
    return BenchConfig(
        scenarios=tuple(parse_scenarios(args.scenarios, folder)),
        methods=methods,
        localizers=localizers,
        out=Path(args.out),
        jobs=int_in_range("-j", args.jobs, 1, 64),
        ray=args.ray,
        missions=folder,
        map=args.map,
        flight_date=flight_dates(args.map_date)[0],
        reference_date=int_in_range("--reference-date", args.reference_date, 0, 99),
        align=args.align,
        seed=int_in_range("--seed", args.seed, 0, 2**31 - 1),
        wait_timeout_s=(
            None
            if args.wait_timeout is None
            else positive_number("--wait-timeout", args.wait_timeout)
        ),
        quiet=bool(args.quiet),
    )


def flight_dates(text: str) -> tuple[int, ...]:
    """``--map-date``: one date index or several, comma-separated, each once."""
    dates = tuple(int_in_range("--map-date", part, 0, 99) for part in str(text).split(","))
    if len(set(dates)) != len(dates):
        msg = f"--map-date {text}: a date is given twice"
        raise OptionError(msg)
    return dates


def run(args: argparse.Namespace) -> int:
    """Run the bench (one per flight date); 0 when every cell was measured, 1 when some failed."""
    from air_sitl.bench import resume_problem, run_bench, run_gaps
    from air_sitl.outdir import claim_folder

    config = config_from_args(args)
    dates = flight_dates(args.map_date)
    # A folder holding only archives/ is no run: archives placed there for this bench to
    # reuse (each checked against its inputs before it is measured).
    prepared = config.out.is_dir() and {p.name for p in config.out.iterdir()} == {"archives"}
    if not prepared or args.overwrite:
        claim_folder(
            config.out,
            overwrite=args.overwrite,
            resume=args.resume,
            resume_problem=lambda: resume_problem(config, dates),
        )
    if len(dates) == 1:
        boards = [run_bench(config)]
        sys.stdout.write(boards[0].to_markdown().split("\n## ", 2)[1].join(["## ", "\n"]))
    else:
        boards = run_gaps(config, dates)
        text = (config.out / "leaderboard.md").read_text(encoding="utf-8")
        sys.stdout.write(text.split("\n# reference", 1)[0].rstrip("\n") + "\n")
    sys.stdout.write(f"leaderboard: {config.out / 'leaderboard.md'}\n")
    failed = [r for b in boards for r in b.cells.values() if r.error]
    return 1 if failed else 0
