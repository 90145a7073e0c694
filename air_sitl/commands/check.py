"""``air-sitl check DIR``: validate an archive (ours or an original AIR one, folder or zip)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HELP = "validate a dataset archive: columns, images, 50 Hz cadence, checksums, geometry"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``check``."""
    parser.add_argument("archive", metavar="DIR", help="archive folder or .zip")
    parser.add_argument(
        "--no-images", action="store_true", help="do not decode every image (faster)"
    )


def run(args: argparse.Namespace) -> int:
    """Print the report; exit 0 when the archive is valid, 1 when it is not."""
    from air_sitl.dataset.air_schema import METADATA_CSV, RECORDING_JSON
    from air_sitl.dataset.check import check_archive
    from air_sitl.dataset.reader import open_archive

    folder = Path(args.archive)
    if (folder / RECORDING_JSON).is_file() and not (folder / METADATA_CSV).exists():
        # Killed in its first instants: nothing recorded yet, nothing to be wrong.
        sys.stdout.write(f"{folder}: air-sitl archive, unfinished, no frames yet\nVALID\n")
        return 0
    with open_archive(args.archive) as archive:
        report = check_archive(archive, decode_images=not args.no_images)
    sys.stdout.write(report.text() + "\n")
    return 0 if report.valid else 1
