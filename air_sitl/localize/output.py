"""``estimates/<name>.csv`` written offline in the format the bus recorder writes.

Same columns (:data:`air_sitl.bus.estimates.ESTIMATE_COLUMNS`, pinned by a test), same number
formats; the latency columns stay empty (no frame was published). The file is written under a
temporary name and renamed into place, then listed in ``manifest.json`` like the bus
recorder's logs (``wall_clock_files`` included).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable
from pathlib import Path

from air_sitl.dataset.air_schema import ESTIMATES_DIR
from air_sitl.dataset.manifest import refresh_manifest, sha256_bytes
from air_sitl.errors import DatasetError
from air_sitl.frames import ned2geodetic
from air_sitl.localize.base import Estimate
from air_sitl.state import GeoPoint

ESTIMATE_COLUMNS = (
    "sim_time_ns",
    "frame",
    "east_m",
    "north_m",
    "up_m",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "qw",
    "qx",
    "qy",
    "qz",
    "latency_wall_ms",
    "latency_frames",
)
ESTIMATE_HEADER = ",".join(ESTIMATE_COLUMNS) + "\n"


def estimate_row(est: Estimate, home: GeoPoint | None) -> str:
    """One CSV line (with its newline), formatted as the bus recorder formats it."""
    enu = est.enu_m
    if enu is not None and not all(math.isfinite(c) for c in enu):
        enu = None
    geo = ("", "", "")
    if enu is not None and home is not None:
        lat, lon, alt = ned2geodetic(
            enu[1], enu[0], -enu[2], home.lat_deg, home.lon_deg, home.alt_amsl_m
        )
        geo = (f"{lat:.9f}", f"{lon:.9f}", f"{alt:.4f}")
    pos = ("nan", "nan", "nan") if enu is None else tuple(f"{c:.4f}" for c in enu)
    q = est.q_body_to_ned_wxyz
    quat = ("", "", "", "") if q is None else tuple(f"{c:.8f}" for c in q)
    return ",".join((str(est.sim_time_ns), str(est.frame), *pos, *geo, *quat, "", "")) + "\n"


def write_estimates(
    archive: Path, name: str, estimates: Iterable[Estimate], home: GeoPoint | None
) -> Path:
    """Write ``archive/estimates/<name>.csv`` atomically and list it in the manifest."""
    folder = archive / ESTIMATES_DIR
    path = folder / f"{name}.csv"
    data = (ESTIMATE_HEADER + "".join(estimate_row(e, home) for e in estimates)).encode("ascii")
    tmp = path.with_name(path.name + ".tmp")  # left out of manifests
    try:
        folder.mkdir(parents=True, exist_ok=True)
        tmp.write_bytes(data)
        os.replace(tmp, path)
    except OSError as err:
        tmp.unlink(missing_ok=True)
        msg = f"{path}: cannot write: {err.strerror}"
        raise DatasetError(msg) from None
    refresh_manifest(archive, {f"{ESTIMATES_DIR}/{name}.csv": sha256_bytes(data)})
    return path
