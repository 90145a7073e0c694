"""``estimates/<name>.csv`` written offline in the format the bus recorder writes.

The row format is the recorder's own (:func:`air_sitl.bus.estimates.estimate_row`); the latency
columns stay empty (no frame was published). The file is written under a temporary name and
renamed into place, then listed in ``manifest.json`` like the bus recorder's logs
(``wall_clock_files`` included).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path

from air_sitl.bus import estimates as recorder
from air_sitl.dataset.air_schema import ESTIMATES_DIR
from air_sitl.dataset.manifest import refresh_manifest, sha256_bytes
from air_sitl.files import write_bytes_atomic, write_error
from air_sitl.frames import ned2geodetic
from air_sitl.localize.base import Estimate
from air_sitl.state import GeoPoint

_NO_POSITION = (math.nan, math.nan, math.nan)


def estimate_row(est: Estimate, home: GeoPoint | None) -> str:
    """One CSV line (with its newline): no position unless every coordinate is finite."""
    enu = est.enu_m
    if enu is None or not all(math.isfinite(c) for c in enu):
        return recorder.estimate_row(
            est.sim_time_ns, est.frame, _NO_POSITION, None, est.q_body_to_ned_wxyz, fix=est.fix
        )
    geo = None
    if home is not None:
        lat, lon, alt = ned2geodetic(
            enu[1], enu[0], -enu[2], home.lat_deg, home.lon_deg, home.alt_amsl_m
        )
        geo = GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
    return recorder.estimate_row(
        est.sim_time_ns, est.frame, enu, geo, est.q_body_to_ned_wxyz, fix=est.fix
    )


def write_estimates(
    archive: Path, name: str, estimates: Iterable[Estimate], home: GeoPoint | None
) -> Path:
    """Write ``archive/estimates/<name>.csv`` atomically and list it in the manifest."""
    folder = archive / ESTIMATES_DIR
    path = folder / f"{name}.csv"
    rows = "".join(estimate_row(e, home) for e in estimates)
    data = (recorder.ESTIMATE_HEADER + rows).encode("ascii")
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise write_error(path, err) from None
    write_bytes_atomic(path, data)  # <name>.csv.tmp meanwhile: left out of manifests
    refresh_manifest(archive, {f"{ESTIMATES_DIR}/{name}.csv": sha256_bytes(data)})
    return path
