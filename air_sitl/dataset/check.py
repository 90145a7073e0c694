"""Validate an archive against the AIR contract and our own guarantees (``air-sitl check``).

Sealed archives of ours must match their manifest byte for byte. Unfinished ones (a recording
that was killed) must hold only whole frames: every row's image in place, a torn last line at
most; they are valid so far (exit 3, not 0) and ``--resume`` continues them. Original AIR
archives (no manifest, no ``frames.csv``) get the checks that apply to what they have.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import PurePosixPath

import cv2
import numpy as np

from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.dataset.air_schema import (
    FRAMES_CSV,
    IMU_COLUMNS,
    IMU_CSV,
    MANIFEST_JSON,
    frame_index_of,
)
from air_sitl.dataset.manifest import manifest_home, sha256_bytes
from air_sitl.dataset.reader import AirRow, Archive
from air_sitl.files import TMP_SUFFIX
from air_sitl.frames import geodetic2ned, ned2geodetic
from air_sitl.state import GeoPoint

EXIT_VALID, EXIT_INVALID, EXIT_INCOMPLETE = 0, 1, 3  # check's exit codes (docs/archives.md)
INCOMPLETE_VERDICT = (
    "INCOMPLETE: valid so far, but the recording did not finish (--resume with the same "
    "command and options finishes it)"
)
POSITION_TOLERANCE_M = 0.5
QUAT_NORM_TOLERANCE = 1e-3
MAX_LISTED = 8  # problems of one kind listed before "... and N more"


@dataclass(slots=True)
class CheckReport:
    """What ``check`` found: facts for the summary line, errors (invalid) and notes."""

    path: str
    kind: str = "?"  # "air-sitl" or "air"
    status: str = "?"  # "complete", "unfinished" or "original AIR"
    frames: int = 0
    image_size: tuple[int, int] | None = None
    errors: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    max_position_error_m: float | None = None
    duration_s: float | None = None

    unfinished: bool = False  # a recording that did not finish (valid so far: --resume)

    @property
    def valid(self) -> bool:
        """True when no error was found."""
        return not self.errors

    @property
    def exit_code(self) -> int:
        """``check``'s exit code: 0 valid and complete, 1 invalid, 3 valid so far but
        unfinished (the recording was interrupted: ``--resume`` finishes it)."""
        if not self.valid:
            return EXIT_INVALID
        return EXIT_INCOMPLETE if self.unfinished else EXIT_VALID

    def verdict(self) -> str:
        """The last line of the report: the verdict, one line, matching :attr:`exit_code`."""
        if not self.valid:
            return f"INVALID ({len(self.errors)} errors)"
        if self.unfinished:
            return INCOMPLETE_VERDICT
        return "VALID"

    def text(self) -> str:
        """The short report ``check`` prints."""
        size = f" {self.image_size[0]}x{self.image_size[1]}" if self.image_size else ""
        head = f"{self.path}: {self.kind} archive, {self.status}, {self.frames} frames{size}"
        if self.duration_s is not None:
            head += f", {self.duration_s:.1f} s"
        lines = [head]
        if self.max_position_error_m is not None:
            lines.append(f"  lat/lon vs PoseX/PoseY: max {self.max_position_error_m:.3f} m")
        lines += [f"  note: {n}" for n in self.notes]
        lines += [f"  error: {e}" for e in _listed(self.errors)]
        lines.append(self.verdict())
        return "\n".join(lines)


def _listed(items: list[str]) -> list[str]:
    if len(items) <= 2 * MAX_LISTED:
        return items
    return [*items[: 2 * MAX_LISTED], f"... and {len(items) - 2 * MAX_LISTED} more"]


class _Problems:
    """Collects problems by kind so that one bad column does not print 10,000 lines."""

    def __init__(self) -> None:
        self.by_kind: dict[str, list[str]] = {}

    def add(self, kind: str, text: str) -> None:
        self.by_kind.setdefault(kind, []).append(text)

    def lines(self) -> list[str]:
        out: list[str] = []
        for items in self.by_kind.values():
            out += items[:MAX_LISTED]
            if len(items) > MAX_LISTED:
                out.append(f"{items[0].split(':')[0]}: ... and {len(items) - MAX_LISTED} more")
        return out


def _home_from_rows(rows: list[AirRow]) -> GeoPoint:
    """Home of an archive without a manifest: the point the first row's pose is relative to."""
    r = rows[0]
    e, n = r.pose_enu_m[0], r.pose_enu_m[1]
    lat0, lon0, _ = ned2geodetic(-n, -e, 0.0, r.lat_deg, r.lon_deg, 0.0)
    for _ in range(3):
        dn, de, _ = geodetic2ned(r.lat_deg, r.lon_deg, 0.0, lat0, lon0, 0.0)
        lat0, lon0, _ = ned2geodetic(dn - n, de - e, 0.0, lat0, lon0, 0.0)
    return GeoPoint(lat_deg=lat0, lon_deg=lon0, alt_amsl_m=0.0)


def _check_rows(archive: Archive, report: CheckReport, problems: _Problems) -> None:
    home = manifest_home(archive.manifest) or _home_from_rows(archive.rows)
    worst = 0.0
    for k, r in enumerate(archive.rows):
        where = f"metadata.csv line {k + 2}"
        name = PurePosixPath(r.filename)
        if name.is_absolute() or ".." in name.parts or not r.filename:
            problems.add("name", f"{where}: Filename {r.filename!r} is not relative to the folder")
        values = (r.lat_deg, r.lon_deg, r.rel_alt_m, *r.pose_enu_m, *r.orientation_xyzw)
        if not all(math.isfinite(v) for v in values):
            problems.add("finite", f"{where}: a position or orientation value is not finite")
            continue
        for label, q in (("Orientation", r.orientation_xyzw), ("Imu", r.imu_xyzw)):
            norm = math.sqrt(sum(c * c for c in q))
            if math.isfinite(norm) and abs(norm - 1.0) > QUAT_NORM_TOLERANCE:
                problems.add("quat", f"{where}: {label}X..W has norm {norm:.4f}, expected 1")
        alt = home.alt_amsl_m + r.rel_alt_m
        n, e, _d = geodetic2ned(r.lat_deg, r.lon_deg, alt, *_home_tuple(home))
        err = math.hypot(e - r.pose_enu_m[0], n - r.pose_enu_m[1])
        worst = max(worst, err)
        if err > POSITION_TOLERANCE_M and archive.kind != "air":
            problems.add(
                "pose",
                f"{where}: PoseX/PoseY is {err:.2f} m from Latitude/Longitude "
                f"(tolerance {POSITION_TOLERANCE_M} m)",
            )
    report.max_position_error_m = worst if archive.rows else None
    if archive.kind == "air" and worst > POSITION_TOLERANCE_M:
        # AIR's Latitude/Longitude may come from a noisy GPS: report, do not fail.
        report.notes.append(
            f"Latitude/Longitude differ from PoseX/PoseY by up to {worst:.2f} m "
            "(home estimated from the first row)"
        )


def _home_tuple(home: GeoPoint) -> tuple[float, float, float]:
    return (home.lat_deg, home.lon_deg, home.alt_amsl_m)


def _check_images(
    archive: Archive, report: CheckReport, problems: _Problems, expected: tuple[int, int] | None
) -> None:
    def size_of(k: int) -> tuple[int, int] | str:
        name = archive.rows[k].filename
        if not archive.exists(name):
            return f"metadata.csv line {k + 2}: image {name} is missing"
        data = archive.read_bytes(name)
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        if image is None:
            return f"metadata.csv line {k + 2}: image {name} does not decode"
        return (int(image.shape[1]), int(image.shape[0]))

    with ThreadPoolExecutor(max_workers=2) as pool:
        sizes = list(pool.map(size_of, range(len(archive.rows))))
    for k, size in enumerate(sizes):
        if isinstance(size, str):
            problems.add("image", size)
            continue
        if expected is None:
            expected = size
        if size != expected:
            problems.add(
                "size",
                f"metadata.csv line {k + 2}: image {archive.rows[k].filename} is "
                f"{size[0]}x{size[1]}, expected {expected[0]}x{expected[1]}",
            )
    report.image_size = expected


def _check_frames_csv(
    archive: Archive, report: CheckReport, problems: _Problems, unfinished: bool
) -> None:
    extra = archive.extra_rows or []
    n_meta = len(archive.rows)
    if len(extra) != n_meta and not unfinished:
        problems.add("count", f"{FRAMES_CSV}: {len(extra)} rows, metadata.csv has {n_meta}")
    if archive.extra_torn_tail:
        if unfinished:
            report.notes.append(f"{FRAMES_CSV}: torn last line (interrupted write)")
        else:
            problems.add("torn", f"{FRAMES_CSV}: the last line has no newline")
    previous: int | None = None
    gaps = 0
    for k, row in enumerate(extra[:n_meta]):
        where = f"{FRAMES_CSV} line {k + 2}"
        try:
            index = int(row.get("frame", ""))
            t = int(row.get("sim_time_ns", ""))
        except ValueError:
            problems.add("frames", f"{where}: frame or sim_time_ns is not an integer")
            continue
        if index != k or row.get("filename") != archive.rows[k].filename:
            problems.add("frames", f"{where}: frame {index} / {row.get('filename')} out of step")
        if t % CAMERA_PERIOD_NS:
            problems.add("cadence", f"{where}: sim_time_ns {t} is not on the 50 Hz grid")
        meta = archive.rows[k]
        try:
            same = (
                abs(float(row["lat_deg"]) - meta.lat_deg) < 1e-9
                and abs(float(row["lon_deg"]) - meta.lon_deg) < 1e-9
            )
            gps_t = row.get("gps_time_ns", "")
            future = gps_t.lstrip("-").isdigit() and int(gps_t) > t
        except (KeyError, ValueError):
            same, future = False, False
        if not same:
            problems.add("agree", f"{where}: lat/lon differ from metadata.csv line {k + 2}")
        if future:
            problems.add("gps", f"{where}: GPS fix time {gps_t} is after the frame time {t}")
        if previous is not None:
            dt = t - previous
            if dt <= 0:
                problems.add("cadence", f"{where}: time does not increase ({dt} ns)")
            elif dt != CAMERA_PERIOD_NS:
                gaps += 1
        previous = t
    if gaps:
        report.notes.append(f"{FRAMES_CSV}: {gaps} gaps between capture windows")
    if extra[:n_meta]:
        try:
            t0 = int(extra[0]["sim_time_ns"])
            t1 = int(extra[min(n_meta, len(extra)) - 1]["sim_time_ns"])
            report.duration_s = (t1 - t0 + CAMERA_PERIOD_NS) / 1e9
        except (KeyError, ValueError):
            pass


def _check_imu(
    archive: Archive, report: CheckReport, problems: _Problems, unfinished: bool
) -> None:
    """``imu.csv``: its header, and one row per physics step with increasing timestamps."""
    if not archive.exists(IMU_CSV):
        if not unfinished:
            problems.add("imu", f"{IMU_CSV}: missing")
        return
    text = archive.read_bytes(IMU_CSV).decode("ascii", errors="replace")
    if unfinished and ",".join(IMU_COLUMNS).startswith(text.rstrip("\n")):
        report.notes.append(f"{IMU_CSV}: no samples yet")
        return
    lines = text.split("\n")
    if lines[0].split(",") != list(IMU_COLUMNS):
        problems.add("imu", f"{IMU_CSV}: header is not {','.join(IMU_COLUMNS)}")
        return
    if lines[-1]:
        if unfinished:
            report.notes.append(f"{IMU_CSV}: torn last line (interrupted write)")
        else:
            problems.add("imu", f"{IMU_CSV}: the last line has no newline")
    body = lines[1:-1]
    previous: int | None = None
    step: int | None = None
    for k, line in enumerate(body, start=2):
        fields = line.split(",")
        try:
            t = int(fields[0])
            values = [float(x) for x in fields[1:]]
        except ValueError:
            problems.add("imu", f"{IMU_CSV} line {k}: not numbers")
            continue
        if len(values) != len(IMU_COLUMNS) - 1 or not all(math.isfinite(v) for v in values):
            problems.add("imu", f"{IMU_CSV} line {k}: expected {len(IMU_COLUMNS)} finite values")
        if previous is not None:
            dt = t - previous
            if step is None:
                step = dt
            if dt <= 0 or dt != step:
                problems.add("imu", f"{IMU_CSV} line {k}: step {dt} ns, expected {step} ns")
        previous = t
    if step:
        report.notes.append(f"{IMU_CSV}: {len(body)} samples at {1e9 / step:.0f} Hz")


def _check_manifest(archive: Archive, problems: _Problems) -> None:
    manifest = archive.manifest or {}
    files = manifest.get("files")
    if not isinstance(files, dict):
        problems.add("manifest", f"{MANIFEST_JSON}: no 'files' table")
        return
    if manifest.get("frame_count") != len(archive.rows):
        problems.add(
            "manifest",
            f"{MANIFEST_JSON}: frame_count {manifest.get('frame_count')} but metadata.csv "
            f"has {len(archive.rows)} rows",
        )
    present = set(archive.names())
    for name, digest in sorted(files.items()):
        if name not in present:
            problems.add("missing", f"{name}: listed in the manifest but missing")
            continue
        if sha256_bytes(archive.read_bytes(name)) != digest:
            problems.add("hash", f"{name}: SHA-256 differs from the manifest")
    for name in sorted(present - set(files) - {MANIFEST_JSON}):
        if not any(part.startswith(".") for part in PurePosixPath(name).parts):
            problems.add("unlisted", f"{name}: present but not in the manifest")


def _expected_size(archive: Archive) -> tuple[int, int] | None:
    camera = archive.camera() or {}
    try:
        return (int(camera["image_width"]), int(camera["image_height"]))
    except (KeyError, TypeError, ValueError):
        return None


def check_archive(archive: Archive, *, decode_images: bool = True) -> CheckReport:
    """Run every check that applies to ``archive`` and return the report."""
    report = CheckReport(path=str(archive.path), kind=archive.kind, frames=len(archive.rows))
    problems = _Problems()
    unfinished = not archive.complete and (
        archive.recording is not None or archive.kind == "air-sitl"
    )
    if archive.complete:
        report.status = "complete"
    elif unfinished:
        report.status = "unfinished"
        report.unfinished = True
    else:
        report.status = "original AIR (no manifest)"
    if archive.manifest is not None and not archive.complete:
        problems.add("manifest", f"{MANIFEST_JSON}: present but not marked complete")
    if archive.torn_tail:
        if unfinished:
            report.notes.append("metadata.csv: torn last line (interrupted write)")
        else:
            problems.add("torn", "metadata.csv: the last line has no newline")
    if archive.kind == "air-sitl":
        if archive.camera() is None:
            if unfinished and not archive.exists("camera.yaml"):
                report.notes.append("camera.yaml: not written yet")
            else:
                problems.add("camera", "camera.yaml: missing or not a YAML mapping")
        _check_frames_csv(archive, report, problems, unfinished)
        _check_imu(archive, report, problems, unfinished)
    if archive.rows:
        _check_rows(archive, report, problems)
        if decode_images:
            _check_images(archive, report, problems, _expected_size(archive))
    elif not unfinished:
        problems.add("empty", "metadata.csv: no frames")
    if archive.complete:
        _check_manifest(archive, problems)
    if unfinished:
        names = archive.names()
        stray = [n for n in names if n.endswith(TMP_SUFFIX)]
        later = [
            n
            for n in names
            if (i := frame_index_of(PurePosixPath(n).name)) is not None and i >= len(archive.rows)
        ]
        if stray or later:
            report.notes.append(
                f"{len(later)} images past the last row and {len(stray)} temporary files "
                "(removed by --resume)"
            )
        report.notes.append("no manifest: the recording did not finish")
    report.errors = problems.lines()
    return report
