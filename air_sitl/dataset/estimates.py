"""External position estimates in an archive: ``estimates/<name>.csv`` and AIR's SvoX..SvoZ.

Estimators (the zenoh bus logs them) write ``estimates/<name>.csv`` with a header. This module
reads any such file whose columns name a time (``sim_time_ns`` / ``timestamp_ns`` or a
``frame`` index) and a position (ENU ``east_m,north_m,up_m`` or ``x_m,y_m,z_m``, or WGS84
``lat_deg,lon_deg`` with ``alt_amsl_m``/``alt_m``), and fills AIR's Svo columns from one
estimator with :func:`fill_svo_columns`.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from air_sitl.dataset.air_schema import AIR_COLUMNS, AIR_HEADER, ESTIMATES_DIR, METADATA_CSV
from air_sitl.dataset.manifest import refresh_manifest, sha256_bytes
from air_sitl.errors import DatasetError
from air_sitl.files import write_bytes_atomic
from air_sitl.frames import geodetic2ned
from air_sitl.state import GeoPoint, Quat, Vec3

_TIME_COLUMNS = ("sim_time_ns", "timestamp_ns", "t_ns", "time_ns")
_ENU_COLUMNS = (
    ("east_m", "north_m", "up_m"),
    ("enu_e_m", "enu_n_m", "enu_u_m"),
    ("x_m", "y_m", "z_m"),
    ("x", "y", "z"),
)
_GEO_COLUMNS = (
    ("lat_deg", "lon_deg", "alt_amsl_m"),
    ("lat_deg", "lon_deg", "alt_m"),
    ("latitude", "longitude", "altitude"),
)
_Q_NED_COLUMNS = ("qw", "qx", "qy", "qz")


@dataclass(frozen=True, slots=True, kw_only=True)
class EstimatePoint:
    """One estimate: when, which frame, ENU position relative to home, optional attitude."""

    sim_time_ns: int | None
    frame: int | None
    enu_m: Vec3
    q_body_to_ned_wxyz: Quat | None


def estimate_path(archive: Path, name: str) -> Path:
    """Where the estimator ``name`` is logged in an archive folder."""
    return archive / ESTIMATES_DIR / f"{name}.csv"


def _pick(header: list[str], options: tuple[tuple[str, ...], ...]) -> tuple[str, ...] | None:
    for cols in options:
        if all(c in header for c in cols):
            return cols
    return None


def read_estimates(path: Path, home: GeoPoint | None) -> list[EstimatePoint]:
    """Read ``estimates/<name>.csv`` (see the module docstring for the accepted columns)."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as err:
        msg = f"{path}: cannot read the estimates: {err}"
        raise DatasetError(msg) from None
    return parse_estimates(text, str(path), home)


def parse_estimates(text: str, path: str, home: GeoPoint | None) -> list[EstimatePoint]:
    """Parse the text of an estimates file; ``path`` names it in error messages."""
    if not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]  # a torn last line (interrupted write)
    rows = list(csv.DictReader(io.StringIO(text)))
    header = list(rows[0].keys()) if rows else []
    time_col = next((c for c in _TIME_COLUMNS if c in header), None)
    enu_cols = _pick(header, _ENU_COLUMNS)
    geo_cols = None if enu_cols else _pick(header, _GEO_COLUMNS)
    if rows and (time_col is None and "frame" not in header):
        msg = f"{path}: no time column (expected one of {', '.join(_TIME_COLUMNS)} or frame)"
        raise DatasetError(msg)
    if rows and enu_cols is None and geo_cols is None:
        msg = f"{path}: no position columns (expected east_m,north_m,up_m or lat_deg,lon_deg,alt_m)"
        raise DatasetError(msg)
    if geo_cols is not None and home is None:
        msg = f"{path}: geodetic estimates need the archive's home (manifest.json)"
        raise DatasetError(msg)
    points: list[EstimatePoint] = []
    for k, row in enumerate(rows, start=2):
        try:
            t = int(row[time_col]) if time_col and row.get(time_col) else None
            frame = int(row["frame"]) if row.get("frame") not in (None, "") else None
            if enu_cols is not None:
                enu = (float(row[enu_cols[0]]), float(row[enu_cols[1]]), float(row[enu_cols[2]]))
            else:
                assert geo_cols is not None and home is not None
                n, e, d = geodetic2ned(
                    float(row[geo_cols[0]]),
                    float(row[geo_cols[1]]),
                    float(row[geo_cols[2]]),
                    home.lat_deg,
                    home.lon_deg,
                    home.alt_amsl_m,
                )
                enu = (e, n, -d)
            q = None
            if all(row.get(c) not in (None, "") for c in _Q_NED_COLUMNS):
                q = (
                    float(row["qw"]),
                    float(row["qx"]),
                    float(row["qy"]),
                    float(row["qz"]),
                )
        except (TypeError, ValueError) as err:
            msg = f"{path}: line {k}: not a number ({err})"
            raise DatasetError(msg) from None
        if not all(math.isfinite(c) for c in enu):
            continue
        points.append(EstimatePoint(sim_time_ns=t, frame=frame, enu_m=enu, q_body_to_ned_wxyz=q))
    return points


def fill_svo_columns(archive_dir: Path, positions_enu_by_frame: Mapping[int, Vec3]) -> int:
    """Rewrite ``metadata.csv`` with SvoX..SvoZ of the given frames (ENU m, relative to home).

    Frames not in the mapping keep their values. The file is replaced atomically and the
    manifest (when there is one) gets the new hash and any files added since (estimates).
    Returns the number of rows filled.
    """
    path = archive_dir / METADATA_CSV
    try:
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as err:
        msg = f"{path}: cannot read: {err}"
        raise DatasetError(msg) from None
    if not text.startswith(AIR_HEADER):
        msg = f"{path}: the header is not the 20 AIR columns"
        raise DatasetError(msg)
    lines = text[len(AIR_HEADER) :].splitlines(keepends=True)
    n_cols = len(AIR_COLUMNS)
    filled = 0
    out = [AIR_HEADER]
    for k, line in enumerate(lines):
        pos = positions_enu_by_frame.get(k)
        if pos is not None and line.endswith("\n"):
            fields = line[:-1].split(",")
            if len(fields) != n_cols:
                msg = f"{path}: line {k + 2}: {len(fields)} fields, expected {n_cols}"
                raise DatasetError(msg)
            fields[-3:] = ["nan" if math.isnan(c) else f"{c:.4f}" for c in pos]
            out.append(",".join(fields) + "\n")
            filled += 1
        else:
            out.append(line)
    data = "".join(out).encode("ascii")
    write_bytes_atomic(path, data)
    refresh_manifest(archive_dir, {METADATA_CSV: sha256_bytes(data)})
    return filled
