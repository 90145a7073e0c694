"""``air-sitl check DIR``: validate an archive (ours or an original AIR one, folder or zip)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = (
    "validate a dataset archive: columns, images, 50 Hz cadence, checksums, geometry "
    "(exit 0 valid, 1 invalid, 3 valid so far but unfinished)"
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``check``."""
    parser.add_argument("archive", metavar="DIR", help="archive folder or .zip")
    parser.add_argument(
        "--no-images", action="store_true", help="do not decode every image (faster)"
    )


def run(args: argparse.Namespace) -> int:
    """Print the report and its verdict; exit 0 valid and complete, 1 invalid, 3 valid so far
    but unfinished (an interrupted recording: ``--resume`` finishes it)."""
    from air_sitl.dataset.air_schema import METADATA_CSV, RECORDING_JSON
    from air_sitl.dataset.check import EXIT_INCOMPLETE, INCOMPLETE_VERDICT, check_archive
    from air_sitl.dataset.reader import open_archive
    from air_sitl.files import TMP_SUFFIX

    folder = Path(args.archive)
    if folder.is_dir() and not (folder / METADATA_CSV).exists():
        names = [p.name for p in folder.iterdir()]
        if names and all(n.startswith(RECORDING_JSON) or n.endswith(TMP_SUFFIX) for n in names):
            # Stopped in its first instants: nothing recorded yet, nothing to be wrong.
            sys.stdout.write(
                f"{folder}: air-sitl archive, unfinished, no frames yet\n{INCOMPLETE_VERDICT}\n"
            )
            return EXIT_INCOMPLETE
    with open_archive(args.archive) as archive:
        report = check_archive(archive, decode_images=not args.no_images)
    sys.stdout.write(report.text() + "\n")
    return report.exit_code
