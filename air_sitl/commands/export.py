"""``air-sitl export DIR``: an archive as rosbag2 (MCAP), rosbag1 or TUM trajectories."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from air_sitl.errors import OptionError
from air_sitl.outdir import add_out_arguments

HELP = "export an archive as a rosbag2 (MCAP) folder, a rosbag1 file or a TUM trajectory"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``export``."""
    parser.add_argument("archive", metavar="DIR", help="archive folder or .zip")
    what = parser.add_mutually_exclusive_group(required=True)
    what.add_argument("--rosbag2", metavar="OUT", help="rosbag2 folder to create (MCAP storage)")
    what.add_argument("--rosbag1", metavar="OUT.bag", help="rosbag1 file to create")
    what.add_argument("--tum", metavar="OUT.txt", help="TUM trajectory file (ground truth)")
    what.add_argument(
        "--mcap",
        metavar="FILE",
        help="MCAP file of the Foxglove topics (those of fly --foxglove; extra air-sitl[foxglove])",
    )
    parser.add_argument(
        "--estimate",
        metavar="NAME",
        default=None,
        help="with --tum: write estimates/NAME.csv instead of the ground truth ('svo': SvoX..Z)",
    )
    add_out_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Export; exit 0 on success."""
    from air_sitl.dataset.export import export_rosbag, export_tum
    from air_sitl.dataset.reader import open_archive
    from air_sitl.outdir import claim_path
    from air_sitl.progress import Progress

    if args.estimate is not None and args.tum is None:
        msg = "--estimate: only with --tum"
        raise OptionError(msg)
    if args.mcap is not None:
        from air_sitl.foxglove.commands import export_mcap_command

        return export_mcap_command(args.archive, Path(args.mcap), overwrite=args.overwrite)
    target = Path(next(p for p in (args.tum, args.rosbag1, args.rosbag2) if p is not None))
    with open_archive(args.archive) as archive:
        claim_path(target, overwrite=args.overwrite, folder=args.rosbag2 is not None)
        if args.tum is not None:
            n = export_tum(archive, Path(args.tum), args.estimate)
            sys.stdout.write(f"{args.tum}: {n} poses\n")
            return 0
        out = Path(args.rosbag1 if args.rosbag1 is not None else args.rosbag2)
        with Progress(f"export {out.name}", len(archive.rows), unit="frames") as bar:
            counts = export_rosbag(
                archive,
                out,
                ros1=args.rosbag1 is not None,
                progress=lambda done, _total: bar.update_to(done),
            )
    total = sum(counts.values())
    detail = ", ".join(f"{t} {n}" for t, n in sorted(counts.items()))
    sys.stdout.write(f"{out}: {total} messages ({detail})\n")
    return 0
