"""How many bytes a recording will take on disk, from its frames and the camera's JPEG quality;
and the free space where it goes (``dataset`` says the first and refuses when the second is
smaller).

The table is measured, not modelled: ``benchmarks/bench_frame_bytes.py`` renders 640x480
frames with the default noise (1.8 grey levels) over the procedural ``urban`` and ``forest``
maps at 200 m and 300 m above the ground (AIR's altitudes) and encodes them at each quality;
the figures are the mean over both maps and altitudes (2026-11-28: urban 200 m 87.8 kB and
300 m 109.9 kB at q90, forest 83.4 kB and 102.9 kB). A flown UC-300 (3284 frames at q90)
wrote 108.8 kB per JPEG and 5.4 kB per frame of CSV tables (imu.csv the most). Other sizes
scale with the pixel count; GeoTIFF imagery, other noise or effects change the figure (noise
costs bytes: it does not compress).
"""

from __future__ import annotations

import bisect
import os
import shutil
from pathlib import Path

# JPEG quality -> mean bytes of one 640x480 frame (benchmarks/bench_frame_bytes.py).
JPEG_BYTES_640X480: tuple[tuple[int, int], ...] = (
    (1, 8_000),  # below 50 not measured: JPEG's floor for such frames, roughly
    (50, 38_225),
    (60, 43_543),
    (70, 51_754),
    (75, 56_814),
    (80, 64_805),
    (85, 75_994),
    (90, 96_001),
    (95, 140_636),
    (100, 280_462),
)
TABLE_BYTES_PER_FRAME = 5_400  # metadata.csv, frames.csv, imu.csv, trajectory.csv per frame
_REFERENCE_PX = 640 * 480


def jpeg_bytes_per_frame(quality: int, width_px: int = 640, height_px: int = 480) -> float:
    """Expected JPEG bytes of one frame at ``quality`` (1..100), linear between the table's
    qualities and scaled by the pixel count."""
    q = min(100, max(1, quality))
    qualities = [row[0] for row in JPEG_BYTES_640X480]
    i = bisect.bisect_left(qualities, q)
    if qualities[i] == q:
        per_frame = float(JPEG_BYTES_640X480[i][1])
    else:
        (q0, b0), (q1, b1) = JPEG_BYTES_640X480[i - 1], JPEG_BYTES_640X480[i]
        per_frame = b0 + (b1 - b0) * (q - q0) / (q1 - q0)
    return per_frame * (width_px * height_px) / _REFERENCE_PX


def recording_bytes(frames: int, quality: int, width_px: int = 640, height_px: int = 480) -> int:
    """Expected bytes of a recording of ``frames`` camera frames (images and tables)."""
    per_frame = jpeg_bytes_per_frame(quality, width_px, height_px) + TABLE_BYTES_PER_FRAME
    return round(frames * per_frame)


def free_bytes(path: Path) -> int:
    """Free bytes (for this user) on the file system that holds ``path`` or would hold it
    (its nearest existing parent folder)."""
    probe = path.absolute()
    while not probe.exists() and probe != probe.parent:
        probe = probe.parent
    return shutil.disk_usage(probe).free


def frames_on_disk(folder: Path) -> int:
    """Frames a (resumed) recording folder already holds."""
    try:
        with os.scandir(folder) as entries:
            return sum(
                1 for e in entries if e.name.startswith("frame_") and e.name.endswith(".jpg")
            )
    except OSError:
        return 0


def complete_frames(folder: Path) -> int | None:
    """Frames of a recording folder that is complete (its manifest written last), else None:
    what ``--resume`` skips."""
    from air_sitl.dataset.air_schema import MANIFEST_JSON

    return frames_on_disk(folder) if (folder / MANIFEST_JSON).is_file() else None


def human_bytes(n: float) -> str:
    """``10.8 GB``, ``512 MB``, ``3.1 kB`` (decimal units, as disk makers and ``df -H``)."""
    for unit, scale in (("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if abs(n) >= scale:
            return f"{n / scale:.1f} {unit}"
    return f"{n:.0f} B"
