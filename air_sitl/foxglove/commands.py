"""What the commands call: importable without the SDK (it is checked here, with one line)."""

from __future__ import annotations

import sys
from pathlib import Path

from air_sitl.foxglove import require_sdk


def export_mcap_command(archive_path: str, out: Path) -> int:
    """``export ARCHIVE --mcap FILE``: write, print the counts; exit 0."""
    require_sdk("--mcap")
    from air_sitl.dataset.reader import open_archive
    from air_sitl.foxglove.record import export_mcap
    from air_sitl.progress import Progress

    with (
        open_archive(archive_path) as archive,
        Progress(f"export {out.name}", len(archive.rows), unit="frames") as bar,
    ):
        counts = export_mcap(archive, out, progress=lambda done, _total: bar.update_to(done))
    total = sum(counts.values())
    detail = ", ".join(f"{t} {n}" for t, n in sorted(counts.items()))
    sys.stdout.write(f"{out}: {total} messages ({detail})\n")
    return 0
