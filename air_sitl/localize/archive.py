"""Offline driver: an archive folder in, ``estimates/<name>.csv`` out.

Builds one :class:`~air_sitl.localize.base.Observation` per capture frame from the archive:

- image: the frame's JPEG (decoded to BGR only for methods that need it);
- IMU and AHRS: ``imu.csv`` as recorded (noise, bias and AHRS drift included); the attitude
  at a frame is the sample at its exposure time;
- barometer and airspeed: the archive has no barometer and its airspeed is truth, so both are
  modelled from the truth in ``frames.csv`` with a seeded noise model
  (:mod:`air_sitl.localize.inputs`; ``--seed``);
- GNSS: the fix ``frames.csv`` records at the first capture frame, and no other, unless the
  manifest records ``gps_denied`` windows: then every new fix outside the windows is given.

``bus_inputs=True`` gives only what the bus carries (no barometer, no airspeed), so that an
offline run reproduces an online one frame for frame.

:func:`run_archive_methods` runs several methods in one pass: each frame read, and decoded
(:mod:`air_sitl.localize.decode`), once for all of them; each method's estimates are the bytes
of its run alone (:func:`run_archive`).
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import math
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.bus.keys import check_chunk
from air_sitl.camera.model import CameraModel
from air_sitl.dataset.air_schema import (
    FRAMES_CSV,
    IMU_COLUMNS,
    IMU_CSV,
    MANIFEST_JSON,
    METADATA_CSV,
)
from air_sitl.dataset.manifest import manifest_home
from air_sitl.dataset.reader import Archive, open_archive
from air_sitl.errors import DatasetError
from air_sitl.localize import base
from air_sitl.localize.inputs import AirspeedModel, BaroModel
from air_sitl.localize.mapmatch import OPEN_MAP_EXTRA, MapOpener
from air_sitl.localize.methods import make_method
from air_sitl.localize.output import write_estimates
from air_sitl.state import Quat

ProgressFn = Callable[[int, int], None]  # (frames done, frames total)


@dataclass(frozen=True, slots=True, kw_only=True)
class LocalizeRun:
    """What one offline run wrote and how fast it went."""

    path: Path
    method: str
    name: str
    frames: int
    estimated_frames: int  # frames with a position
    wall_s: float  # method and driver, reading included
    # What it wrote (``estimates/<name>.csv`` is these against the archive's home)
    estimates: tuple[base.Estimate, ...] = field(default=(), repr=False, compare=False)

    @property
    def frames_per_s(self) -> float:
        """Frames localized per second of wall time."""
        return self.frames / self.wall_s if self.wall_s > 0 else math.inf


@dataclass(frozen=True, slots=True)
class _Imu:
    t_ns: npt.NDArray[np.int64]
    data: npt.NDArray[np.float64]  # gyro xyz, accel xyz, ahrs wxyz


def check_writable(path: Path) -> None:
    """Refuse what offline localization cannot write into (one clear line)."""
    if path.is_file():
        msg = f"{path}: a zip archive is read-only; unzip it to write estimates into it"
        raise DatasetError(msg)
    if not path.is_dir():
        msg = f"{path}: no such archive folder"
        raise DatasetError(msg)


def context_of(
    archive: Archive,
    *,
    reference_map: str | None = None,
    reference_date: int | None = None,
    seed: int = 0,
    open_map: MapOpener | None = None,
) -> base.LocalizerContext:
    """The method's view of an archive before the first frame (home, camera, map, manifest);
    ``open_map``: how map-based methods open their reference map (None: they open it)."""
    where = f"{archive.path}/{MANIFEST_JSON}"
    manifest = archive.manifest
    if manifest is None:
        msg = f"{where}: missing (localize needs an archive recorded by air-sitl)"
        raise DatasetError(msg)
    home = manifest_home(manifest)
    if home is None:
        msg = f"{where}: no usable home ({manifest.get('home')!r})"
        raise DatasetError(msg)
    try:
        cam = manifest.get("camera") or {}
        fields = ("width_px", "height_px", "hfov_deg", "noise_sigma", "jpeg_quality")
        camera = CameraModel(
            **{k: cam[k] for k in fields if k in cam},
            mount_rpy_deg=tuple(float(a) for a in cam.get("mount_rpy_deg", (0.0, 0.0, 0.0))),  # type: ignore[arg-type]
        )
        rate = float(manifest.get("frame_rate_hz", 50.0))
    except (KeyError, TypeError, ValueError) as err:
        msg = f"{where}: no usable camera ({err!r})"
        raise DatasetError(msg) from None
    map_info = manifest.get("map")
    map_date = None
    map_name = None
    if isinstance(map_info, dict):
        di = map_info.get("date_index")
        map_date = int(di) if isinstance(di, int) else None
        map_name = str(map_info.get("kind") or map_info.get("source") or "") or None
    extras: dict[str, Any] = {"archive": archive.path}
    if open_map is not None:
        extras[OPEN_MAP_EXTRA] = open_map
    return base.LocalizerContext(
        home=home,
        camera=camera,
        frame_rate_hz=rate,
        map_date=map_date,
        map_name=map_name,
        reference_map=reference_map,
        reference_date=reference_date,
        seed=seed,
        manifest=manifest,
        extras=extras,
    )


def denial_windows(manifest: dict[str, Any] | None) -> tuple[tuple[int, int], ...]:
    """The GNSS denial windows a manifest records (``gps_denied``), in simulation ns."""
    out = []
    for w in (manifest or {}).get("gps_denied") or ():
        try:
            a = int(w["start_ns"])
            b = 2**63 - 1 if w.get("end_ns") is None else int(w["end_ns"])
        except (KeyError, TypeError, ValueError):
            msg = f"{MANIFEST_JSON}: gps_denied window {w!r}: expected start_ns and end_ns"
            raise DatasetError(msg) from None
        out.append((a, b))
    return tuple(out)


def _read_imu(archive: Archive) -> _Imu:
    where = f"{archive.path}/{IMU_CSV}"
    if not archive.exists(IMU_CSV):
        msg = f"{where}: missing (localize needs the raw IMU of an air-sitl archive)"
        raise DatasetError(msg)
    text = archive.read_bytes(IMU_CSV).decode("ascii", errors="replace")
    header, _, body = text.partition("\n")
    if tuple(header.strip().split(",")) != IMU_COLUMNS:
        msg = f"{where}: header is not {','.join(IMU_COLUMNS)}"
        raise DatasetError(msg)
    if not body.endswith("\n"):
        body = body[: body.rfind("\n") + 1]  # a torn last line
    try:
        table = np.loadtxt(io.StringIO(body), delimiter=",", ndmin=2, dtype=np.float64)
    except ValueError as err:
        msg = f"{where}: not a table of numbers ({err})"
        raise DatasetError(msg) from None
    if table.shape[0] == 0:
        msg = f"{where}: no samples"
        raise DatasetError(msg)
    # float64 holds integer nanoseconds exactly up to 104 days of simulated time
    return _Imu(t_ns=np.rint(table[:, 0]).astype(np.int64), data=table[:, 1:])


def _column(rows: list[dict[str, str]], name: str, where: str) -> npt.NDArray[np.float64]:
    try:
        return np.array([float(r[name]) if r[name] != "" else math.nan for r in rows])
    except (KeyError, ValueError) as err:
        msg = f"{where}: column {name}: {err}"
        raise DatasetError(msg) from None


def observations(
    archive: Archive, *, needs_image: bool, seed: int = 0, bus_inputs: bool = False
) -> Iterator[base.Observation]:
    """The observations of every capture frame, in order (see the module docstring)."""
    where = f"{archive.path}/{FRAMES_CSV}"
    rows = archive.extra_rows
    if rows is None:
        msg = f"{where}: missing (localize needs an archive recorded by air-sitl)"
        raise DatasetError(msg)
    n = min(len(rows), len(archive.rows))
    rows = rows[:n]
    times = np.array([int(r["sim_time_ns"]) for r in rows], dtype=np.int64)
    baro = airspeed = None
    if not bus_inputs and n:
        baro = BaroModel().sample(_column(rows, "alt_rel_m", where), times, seed)
        airspeed = AirspeedModel().sample(_column(rows, "airspeed_m_s", where), seed)
    imu = _read_imu(archive)
    windows = denial_windows(archive.manifest)
    last_fix_t: int | None = None
    prev_t: int | None = None
    for k in range(n):
        r = rows[k]
        t = int(times[k])
        hi = int(np.searchsorted(imu.t_ns, t, side="right"))
        if hi == 0:
            msg = f"{archive.path}/{IMU_CSV}: no sample at or before frame {k} (t={t} ns)"
            raise DatasetError(msg)
        lo = hi - 1 if prev_t is None else int(np.searchsorted(imu.t_ns, prev_t, side="right"))
        readings = tuple(
            base.ImuReading(
                sim_time_ns=int(imu.t_ns[i]),
                gyro_frd_rad_s=(float(d[0]), float(d[1]), float(d[2])),
                accel_frd_m_s2=(float(d[3]), float(d[4]), float(d[5])),
                q_ahrs_body_to_ned_wxyz=(float(d[6]), float(d[7]), float(d[8]), float(d[9])),
            )
            for i in range(lo, hi)
            for d in (imu.data[i],)
        )
        a = imu.data[hi - 1]
        q: Quat = (float(a[6]), float(a[7]), float(a[8]), float(a[9]))
        gnss = _fix_of(r, k, t, last_fix_t, windows)
        if gnss is not None:
            last_fix_t = gnss.sim_time_ns
        jpeg = archive.jpeg(k)
        image = None
        if needs_image:
            decoded = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
            if decoded is None:
                msg = f"{archive.path}/{archive.rows[k].filename}: not a decodable image"
                raise DatasetError(msg)
            image = np.asarray(decoded, dtype=np.uint8)
        yield base.Observation(
            frame=k,
            sim_time_ns=t,
            image_bgr=image,
            imu=readings,
            q_ahrs_body_to_ned_wxyz=q,
            airspeed_m_s=None if airspeed is None else float(airspeed[k]),
            baro_alt_rel_m=None if baro is None else float(baro[k]),
            gnss=gnss,
            jpeg=jpeg,
        )
        prev_t = t


def gnss_fix_of_row(row: Mapping[str, str]) -> base.GnssFix:
    """The GNSS time, position and velocity of one ``frames.csv`` row (KeyError or ValueError
    when it has none)."""
    return base.GnssFix(
        sim_time_ns=int(row["gps_time_ns"]),
        lat_deg=float(row["gps_lat_deg"]),
        lon_deg=float(row["gps_lon_deg"]),
        alt_amsl_m=float(row["gps_alt_amsl_m"]),
        vel_ned_m_s=(
            float(row["gps_vn_m_s"]),
            float(row["gps_ve_m_s"]),
            float(row["gps_vd_m_s"]),
        ),
    )


def _fix_of(
    row: dict[str, str],
    k: int,
    t_ns: int,
    last_fix_t: int | None,
    windows: tuple[tuple[int, int], ...],
) -> base.GnssFix | None:
    """The GNSS fix given at frame ``k``: the first frame's, then only new fixes outside the
    denial windows when the archive records windows."""
    if k > 0 and not windows:
        return None
    try:
        if row.get("gps_fix_type", "") in ("", "0", "1") or not row.get("gps_time_ns"):
            return None
        fix = gnss_fix_of_row(row)
    except (KeyError, ValueError):
        return None
    fix_t = fix.sim_time_ns
    if k == 0:
        return fix
    if fix_t == last_fix_t or any(a <= fix_t < b or a <= t_ns < b for a, b in windows):
        return None
    return fix


def run_method(
    method: base.Localizer,
    context: base.LocalizerContext,
    source: Iterator[base.Observation],
    *,
    total: int,
    progress: ProgressFn | None = None,
) -> list[base.Estimate]:
    """Feed every observation to ``method`` (reset first); one estimate per frame."""
    return run_methods([method], context, source, total=total, progress=progress)[0][0]


def run_methods(
    methods: Sequence[base.Localizer],
    context: base.LocalizerContext,
    source: Iterator[base.Observation],
    *,
    total: int,
    progress: ProgressFn | None = None,
) -> tuple[list[list[base.Estimate]], list[float]]:
    """Feed every observation to each method in turn (each reset first): one estimate per
    frame and method, and the seconds each method took (its reset and steps). A method that
    needs no image is given none, as when it runs alone."""
    seconds = [0.0] * len(methods)
    for i, method in enumerate(methods):
        start = time.perf_counter()
        method.reset(context)
        seconds[i] += time.perf_counter() - start
    out: list[list[base.Estimate]] = [[] for _ in methods]
    for done, obs in enumerate(source, start=1):
        bare = obs if obs.image_bgr is None else replace(obs, image_bgr=None)
        for i, method in enumerate(methods):
            start = time.perf_counter()
            est = method.step(obs if method.needs_image else bare)
            seconds[i] += time.perf_counter() - start
            if est is None:
                est = base.Estimate(frame=obs.frame, sim_time_ns=obs.sim_time_ns, enu_m=None)
            out[i].append(est)
        if progress is not None and (done % 50 == 0 or done == total):
            progress(done, total)
    return out, seconds


def run_archive(
    archive: Path,
    method: str,
    *,
    name: str | None = None,
    reference_map: str | None = None,
    reference_date: int | None = None,
    seed: int = 0,
    bus_inputs: bool = False,
    progress: ProgressFn | None = None,
    options: Mapping[str, Any] | None = None,
    open_map: MapOpener | None = None,
) -> LocalizeRun:
    """Localize every capture frame of ``archive`` with ``method`` (built with ``options``, e.g.
    ``{"every": 4}``); write the estimates file. ``open_map``: see :func:`context_of`."""
    return run_archive_methods(
        archive,
        [(method, name or method, options or {})],
        reference_map=reference_map,
        reference_date=reference_date,
        seed=seed,
        bus_inputs=bus_inputs,
        progress=progress,
        open_map=open_map,
    )[0]


def run_archive_methods(
    archive: Path,
    methods: Sequence[tuple[str, str, Mapping[str, Any]]],
    *,
    reference_map: str | None = None,
    reference_date: int | None = None,
    seed: int = 0,
    bus_inputs: bool = False,
    progress: ProgressFn | None = None,
    open_map: MapOpener | None = None,
) -> list[LocalizeRun]:
    """Several methods, each ``(method, name, options)``, over ``archive`` in one pass (each
    frame read and decoded once); each writes its estimates file, the bytes of its run alone.
    A run's ``wall_s`` is its method's own time and an equal share of the reading."""
    names = [check_chunk("--name", name or method) for method, name, _ in methods]
    check_writable(archive)
    locs = [make_method(method, **options) for method, _, options in methods]
    with open_archive(archive) as arch:
        context = context_of(
            arch,
            reference_map=reference_map,
            reference_date=reference_date,
            seed=seed,
            open_map=open_map,
        )
        start = time.perf_counter()
        needs_image = any(loc.needs_image for loc in locs)
        source = observations(arch, needs_image=needs_image, seed=seed, bus_inputs=bus_inputs)
        estimates, own_s = run_methods(locs, context, source, total=len(arch), progress=progress)
        reading_s = max(0.0, time.perf_counter() - start - sum(own_s)) / max(1, len(locs))
    runs = []
    for (method, _, _), name, found, seconds in zip(methods, names, estimates, own_s, strict=True):
        path = write_estimates(archive, name, found, context.home)
        runs.append(
            LocalizeRun(
                path=path,
                method=method,
                name=name,
                frames=len(found),
                estimated_frames=sum(1 for e in found if e.enu_m is not None),
                wall_s=seconds + reading_s,
                estimates=tuple(found),
            )
        )
    return runs


def imagery_free_inputs(archive: Path) -> str | None:
    """The identity of what a method that reads no imagery is given from ``archive``
    (:func:`~air_sitl.localize.methods.reads_imagery`): the SHA-256 of the manifest's hashes
    of ``frames.csv`` (times, sensors, GNSS), ``imu.csv`` and ``metadata.csv`` (the truth
    eval scores against), with its home, camera, frame rate and GNSS denial windows. The
    archives of one flight at several map dates share it; None when the manifest does not
    record those hashes (an archive still being written, or not air-sitl's)."""
    try:
        manifest = json.loads((archive / MANIFEST_JSON).read_text(encoding="utf-8"))
        files = manifest["files"]
        inputs = {
            "files": [files[name] for name in (FRAMES_CSV, IMU_CSV, METADATA_CSV)],
            **{k: manifest.get(k) for k in ("home", "camera", "frame_rate_hz", "gps_denied")},
        }
    except (OSError, ValueError, KeyError, TypeError):
        return None
    text = json.dumps(inputs, sort_keys=True, allow_nan=True)
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def read_rows(path: Path) -> list[dict[str, str]]:
    """The rows of a CSV file (tests, benchmarks)."""
    with path.open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))
