"""File formats at the boundary: an archive's truth, and the estimate sources.

A SOURCE is, tried in this order:

- a name: ``ARCHIVE/estimates/NAME.csv`` (what the bus recorder writes);
- ``svo``: AIR's SvoX..SvoZ columns of ``metadata.csv`` (an original AIR archive's baseline);
- a path to a CSV in the recorder's format (``sim_time_ns`` and/or ``frame``; ENU
  ``east_m,north_m,up_m`` or ``lat_deg,lon_deg,alt_amsl_m``; optional ``latency_wall_ms``
  and ``fix``: 1 a map fix accepted at the row's frame, 0 none, empty unsaid);
- a path to a TUM file ``t x y z qx qy qz qw`` (t simulated seconds, ENU metres from home, as
  ``air-sitl export --tum`` writes).

Everything is validated here once; a bad value is an :class:`EvalError` naming the file, the
line and the value. A row whose position columns are all empty or ``nan`` is "no estimate".
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from air_sitl.dataset.air_schema import ESTIMATES_DIR, METADATA_CSV
from air_sitl.dataset.manifest import manifest_home
from air_sitl.dataset.reader import Archive
from air_sitl.eval.cells import Triple, check_time_order, integer, number, triple
from air_sitl.eval.errors import EvalError
from air_sitl.eval.trajectory import F64, I64, NO_FRAME, NO_TIME, Bools, Estimate, Truth
from air_sitl.files import decode_text
from air_sitl.frames import geodetic2ned
from air_sitl.state import GeoPoint

SVO = "svo"
ENU_COLUMNS = ("east_m", "north_m", "up_m")
GEO_COLUMNS = ("lat_deg", "lon_deg", "alt_amsl_m")
TUM_COLUMNS = ("t", "x", "y", "z", "qx", "qy", "qz", "qw")


def load_truth(archive: Archive) -> Truth:
    """The truth of the archive's capture frames: PoseX..Z, orientation yaw, exposure times."""
    where = f"{archive.path}/{METADATA_CSV}"
    rows = archive.rows
    if not rows:
        msg = f"{where}: no frames, so no truth to score against"
        raise EvalError(msg)
    pos = np.array([r.pose_enu_m for r in rows], dtype=np.float64)
    bad = ~np.isfinite(pos).all(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        value = ",".join(f"{c}" for c in rows[k].pose_enu_m)
        msg = f"{where}: line {k + 2}: PoseX,PoseY,PoseZ = {value}: no truth for this frame"
        raise EvalError(msg)
    q = np.array([r.orientation_xyzw for r in rows], dtype=np.float64)
    x, y, z, w = q.T
    yaw = np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    if not np.isfinite(yaw).all():
        # no orientation: the course of the horizontal track stands in for the heading
        d = np.gradient(pos[:, :2], axis=0) if len(rows) > 1 else np.zeros((1, 2))
        yaw = np.arctan2(d[:, 1], d[:, 0])
    if archive.extra_rows is not None:
        t_ns = np.array([archive.timestamp_ns(k) for k in range(len(rows))], dtype=np.int64)
    else:
        t_ns = np.arange(len(rows), dtype=np.int64) * 20_000_000  # AIR: row k at k/50 s
    return Truth(where=str(archive.path), t_ns=t_ns, pos_enu_m=pos, yaw_enu_rad=yaw)


@dataclass(frozen=True, slots=True)
class _Layout:
    """Where the columns of an estimates CSV are."""

    width: int
    frame: int | None
    time: int | None
    enu: list[int] | None
    geo: list[int] | None
    latency: int | None
    fix: int | None


def parse_csv(text: str, where: str, name: str, home: GeoPoint | None) -> Estimate:
    """Estimates in the bus recorder's CSV format (see the module docstring).

    Parsed column-wise with numpy; a file that does not pass is parsed again row by row to
    name the first bad line and value.
    """
    if not text.strip():
        msg = f"{where}: empty file (expected a header: sim_time_ns,frame,east_m,north_m,up_m,...)"
        raise EvalError(msg)
    reader = csv.reader(io.StringIO(text))
    header = [h.strip() for h in next(reader)]
    col = {h: k for k, h in enumerate(header)}
    if "frame" not in col and "sim_time_ns" not in col:
        msg = f"{where}: line 1: no frame or sim_time_ns column (header {','.join(header)!r})"
        raise EvalError(msg)
    layout = _Layout(
        width=len(header),
        frame=col.get("frame"),
        time=col.get("sim_time_ns"),
        enu=[col[c] for c in ENU_COLUMNS] if all(c in col for c in ENU_COLUMNS) else None,
        geo=[col[c] for c in GEO_COLUMNS] if all(c in col for c in GEO_COLUMNS) else None,
        latency=col.get("latency_wall_ms"),
        fix=col.get("fix"),
    )
    if layout.enu is None and layout.geo is None:
        msg = (
            f"{where}: line 1: no position columns (expected {','.join(ENU_COLUMNS)} or "
            f"{','.join(GEO_COLUMNS)}; header {','.join(header)!r})"
        )
        raise EvalError(msg)
    table = [
        (line, fields)
        for line, fields in enumerate(reader, start=2)
        if fields and not (len(fields) == 1 and not fields[0].strip())
    ]
    fast = _columns(table, layout, home)
    if fast is None:
        fast = _rows(table, layout, home, where)  # raises on the first bad value
    line, frame, t_ns, pos, latency, fix = fast
    return Estimate(
        name=name,
        where=where,
        line=line,
        frame=frame,
        t_ns=t_ns,
        pos_enu_m=pos,
        latency_wall_ms=latency,
        fix=fix,
    )


_Parsed = tuple[I64, I64, I64, F64, F64 | None, F64 | None]
_FIX_VALUES = {"1": 1.0, "0": 0.0, "": math.nan}


def _fix_column(cells: list[str]) -> F64 | None:
    """``fix`` cells as 1, 0 or NaN (empty); None when a cell is anything else."""
    try:
        return np.array([_FIX_VALUES[c.strip()] for c in cells], dtype=np.float64)
    except KeyError:
        return None


def _fix(text: str, where: str, line: int) -> float:
    value = _FIX_VALUES.get(text.strip())
    if value is None:
        msg = f"{where}: line {line}: fix {text!r} is not 1, 0 or empty"
        raise EvalError(msg)
    return value


def _float_column(cells: list[str]) -> F64 | None:
    """Numbers of one column ('' and nan: NaN); None when a cell is text or infinite."""
    arr = np.array([c or "nan" for c in cells], dtype=np.str_)
    try:
        values = arr.astype(np.float64)
    except ValueError:
        return None
    return None if np.isinf(values).any() else values


def _int_column(cells: list[str]) -> tuple[I64, Bools] | None:
    """Integers of one column and where they are present; None when a cell is not one."""
    arr = np.array(cells, dtype=np.str_)
    present = arr != ""
    out = np.zeros(arr.shape[0], dtype=np.int64)
    try:
        out[present] = arr[present].astype(np.int64)
    except (ValueError, OverflowError):
        return None
    return out, present


def _triple_columns(table: list[tuple[int, list[str]]], idx: list[int]) -> F64 | None:
    columns = [_float_column([f[k] for _, f in table]) for k in idx]
    if any(c is None for c in columns):
        return None
    pos = np.column_stack([c for c in columns if c is not None])
    finite = np.isfinite(pos)
    if (finite.any(axis=1) & ~finite.all(axis=1)).any():
        return None
    return pos


def _columns(
    table: list[tuple[int, list[str]]], layout: _Layout, home: GeoPoint | None
) -> _Parsed | None:
    """The whole table column-wise; None when any row needs the row-by-row diagnosis."""
    n = len(table)
    if any(len(f) != layout.width for _, f in table):
        return None
    frame = np.full(n, NO_FRAME, dtype=np.int64)
    t_ns = np.full(n, NO_TIME, dtype=np.int64)
    has_frame = np.zeros(n, dtype=bool)
    has_time = np.zeros(n, dtype=bool)
    for index, target, present in ((layout.frame, frame, has_frame), (layout.time, t_ns, has_time)):
        if index is None:
            continue
        parsed = _int_column([f[index] for _, f in table])
        if parsed is None:
            return None
        values, mask = parsed
        target[mask] = values[mask]
        present[:] = mask
    if not (has_frame | has_time).all():
        return None
    times = t_ns[has_time]
    if times.size > 1 and (np.diff(times) <= 0).any():
        return None
    pos = np.full((n, 3), np.nan)
    if layout.enu is not None:
        enu = _triple_columns(table, layout.enu)
        if enu is None:
            return None
        pos = enu
    if layout.geo is not None:
        geo = _triple_columns(table, layout.geo)
        if geo is None:
            return None
        need = np.flatnonzero(~np.isfinite(pos).all(axis=1) & np.isfinite(geo).all(axis=1))
        if need.size and home is None:
            return None
        for k in need:
            assert home is not None
            lat, lon, alt = (float(v) for v in geo[k])
            north, east, down = geodetic2ned(
                lat, lon, alt, home.lat_deg, home.lon_deg, home.alt_amsl_m
            )
            pos[k] = (east, north, -down)
    latency = None
    if layout.latency is not None:
        latency = _float_column([f[layout.latency] for _, f in table])
        if latency is None:
            return None
    fix = None
    if layout.fix is not None:
        fix = _fix_column([f[layout.fix] for _, f in table])
        if fix is None:
            return None
    line = np.array([k for k, _ in table], dtype=np.int64)
    return line, frame, t_ns, pos, latency, fix


def _rows(
    table: list[tuple[int, list[str]]], layout: _Layout, home: GeoPoint | None, where: str
) -> _Parsed:
    """Row by row, raising :class:`EvalError` on the first bad line and value."""
    lines: list[int] = []
    frames: list[int] = []
    times: list[int] = []
    positions: list[Triple] = []
    latencies: list[float] = []
    fixes: list[float] = []
    nan3 = (math.nan, math.nan, math.nan)
    enu, geo = layout.enu, layout.geo
    for line, fields in table:
        if len(fields) != layout.width:
            msg = f"{where}: line {line}: {len(fields)} fields, expected {layout.width}"
            raise EvalError(msg)
        frame = (
            None if layout.frame is None else integer(fields[layout.frame], where, line, "frame")
        )
        t = (
            None
            if layout.time is None
            else integer(fields[layout.time], where, line, "sim_time_ns")
        )
        if frame is None and t is None:
            msg = f"{where}: line {line}: neither a frame nor a sim_time_ns"
            raise EvalError(msg)
        p_enu = None if enu is None else triple([fields[k] for k in enu], ENU_COLUMNS, where, line)
        p_geo = None if geo is None else triple([fields[k] for k in geo], GEO_COLUMNS, where, line)
        pos = p_enu
        if pos is None and p_geo is not None:
            if home is None:
                msg = (
                    f"{where}: line {line}: a lat/lon estimate needs the archive's home "
                    "(manifest.json) to be scored"
                )
                raise EvalError(msg)
            n, e, d = geodetic2ned(*p_geo, home.lat_deg, home.lon_deg, home.alt_amsl_m)
            pos = (e, n, -d)
        lines.append(line)
        frames.append(NO_FRAME if frame is None else frame)
        times.append(NO_TIME if t is None else t)
        positions.append(nan3 if pos is None else pos)
        if layout.latency is not None:
            latencies.append(number(fields[layout.latency], where, line, "latency_wall_ms"))
        if layout.fix is not None:
            fixes.append(_fix(fields[layout.fix], where, line))
    check_time_order(times, lines, where)
    return (
        np.array(lines, dtype=np.int64),
        np.array(frames, dtype=np.int64),
        np.array(times, dtype=np.int64),
        np.array(positions, dtype=np.float64).reshape(-1, 3),
        None if layout.latency is None else np.array(latencies, dtype=np.float64),
        None if layout.fix is None else np.array(fixes, dtype=np.float64),
    )


def parse_tum(text: str, where: str, name: str) -> Estimate:
    """A TUM trajectory ``t x y z qx qy qz qw`` (simulated seconds, ENU metres from home).

    Parsed column-wise with numpy; a file that does not pass is parsed again line by line to
    name the first bad line and value.
    """
    if not text.strip():
        msg = f"{where}: empty file (expected TUM lines: {' '.join(TUM_COLUMNS)})"
        raise EvalError(msg)
    table = [
        (line, raw.split())
        for line, raw in enumerate(text.splitlines(), start=1)
        if raw.strip() and not raw.lstrip().startswith("#")
    ]
    if not table:
        msg = f"{where}: no TUM lines (only comments)"
        raise EvalError(msg)
    fast = _tum_columns(table)
    line, t_ns, pos = fast if fast is not None else _tum_rows(table, where)
    return Estimate(
        name=name,
        where=where,
        line=line,
        frame=np.full(line.shape[0], NO_FRAME, dtype=np.int64),
        t_ns=t_ns,
        pos_enu_m=pos,
        latency_wall_ms=None,
    )


def _tum_columns(table: list[tuple[int, list[str]]]) -> tuple[I64, I64, F64] | None:
    """The TUM table column-wise; None when a line needs the line-by-line diagnosis."""
    if any(len(parts) != len(TUM_COLUMNS) for _, parts in table):
        return None
    try:
        values = np.array([parts for _, parts in table], dtype=np.str_).astype(np.float64)
    except ValueError:
        return None
    if np.isinf(values).any() or np.isnan(values[:, 0]).any():
        return None
    finite = np.isfinite(values[:, 1:4])
    if (finite.any(axis=1) & ~finite.all(axis=1)).any():
        return None
    t_ns = np.round(values[:, 0] * 1e9).astype(np.int64)
    if t_ns.size > 1 and (np.diff(t_ns) <= 0).any():
        return None
    line = np.array([k for k, _ in table], dtype=np.int64)
    return line, t_ns, values[:, 1:4].copy()


def _tum_rows(table: list[tuple[int, list[str]]], where: str) -> tuple[I64, I64, F64]:
    """Line by line, raising :class:`EvalError` on the first bad line and value."""
    lines: list[int] = []
    times: list[int] = []
    positions: list[Triple] = []
    nan3 = (math.nan, math.nan, math.nan)
    for line, parts in table:
        if len(parts) != len(TUM_COLUMNS):
            shown = " ".join(parts)[:60]
            msg = (
                f"{where}: line {line}: {len(parts)} columns in {shown!r}, expected "
                f"{len(TUM_COLUMNS)} ({' '.join(TUM_COLUMNS)})"
            )
            raise EvalError(msg)
        t_s = number(parts[0], where, line, "t")
        if math.isnan(t_s):
            msg = f"{where}: line {line}: t {parts[0]!r} is not a number"
            raise EvalError(msg)
        pos = triple(parts[1:4], TUM_COLUMNS[1:4], where, line)
        for text_q, column in zip(parts[4:], TUM_COLUMNS[4:], strict=True):
            number(text_q, where, line, column)
        lines.append(line)
        times.append(round(t_s * 1e9))
        positions.append(nan3 if pos is None else pos)
    check_time_order(times, lines, where)
    return (
        np.array(lines, dtype=np.int64),
        np.array(times, dtype=np.int64),
        np.array(positions, dtype=np.float64).reshape(-1, 3),
    )


def svo_estimate(archive: Archive, name: str = SVO) -> Estimate:
    """AIR's SvoX..SvoZ columns as an estimate keyed by frame (all-nan rows: no estimate)."""
    where = f"{archive.path}/{METADATA_CSV}"
    svo = np.array([r.svo_enu_m for r in archive.rows], dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(svo)
    mixed = finite.any(axis=1) & ~finite.all(axis=1)
    if mixed.any():
        k = int(np.argmax(mixed))
        shown = ",".join(f"{c}" for c in svo[k])
        msg = (
            f"{where}: line {k + 2}: SvoX,SvoY,SvoZ = {shown}: some but not all "
            "position columns are empty or nan"
        )
        raise EvalError(msg)
    if np.isinf(svo).any():
        k = int(np.argmax(np.isinf(svo).any(axis=1)))
        msg = f"{where}: line {k + 2}: SvoX,SvoY,SvoZ = {svo[k].tolist()}: not finite"
        raise EvalError(msg)
    n = svo.shape[0]
    return Estimate(
        name=name,
        where=where,
        line=np.arange(2, n + 2, dtype=np.int64),
        frame=np.arange(n, dtype=np.int64),
        t_ns=np.full(n, NO_TIME, dtype=np.int64),
        pos_enu_m=svo,
        latency_wall_ms=None,
    )


def _looks_like_csv(text: str) -> bool:
    for raw in text.splitlines():
        s = raw.strip()
        if s and not s.startswith("#"):
            return "," in s
    return True


def load_estimate(archive: Archive, source: str) -> Estimate:
    """The estimate named by ``source`` (see the module docstring for the lookup order)."""
    inside = f"{ESTIMATES_DIR}/{source}.csv"
    if "/" not in source and archive.exists(inside):
        where = f"{archive.path}/{inside}"
        return parse_csv(
            decode_text(archive.read_bytes(inside), where, EvalError),
            where,
            source,
            manifest_home(archive.manifest),
        )
    if source == SVO:
        return svo_estimate(archive)
    path = Path(source)
    if not path.is_file():
        msg = (
            f"{source}: no such estimate (not {archive.path}/{inside}, not 'svo', "
            "not a CSV or TUM file)"
        )
        raise EvalError(msg)
    try:
        data = path.read_bytes()
    except OSError as err:
        msg = f"{path}: cannot read: {err.strerror}"
        raise EvalError(msg) from None
    text = decode_text(data, str(path), EvalError)
    if _looks_like_csv(text):
        return parse_csv(text, str(path), source, manifest_home(archive.manifest))
    return parse_tum(text, str(path), source)
