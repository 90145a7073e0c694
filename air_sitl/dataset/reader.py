"""Read AIR archives: ours (folders or zips, with ``frames.csv`` and a manifest) and the
original AIR ones (``metadata.csv`` beside the images, no timestamps: row k is at k/50 s).

    import air_sitl.dataset
    with air_sitl.dataset.open("out/FL-200") as archive:
        for frame in archive:
            print(frame.index, frame.timestamp_ns, frame.row.pose_enu_m, frame.image.shape)
"""

from __future__ import annotations

import csv
import io
import json
import math
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import yaml

from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.closeable import Closeable
from air_sitl.dataset.air_schema import (
    AIR_COLUMNS,
    CAMERA_YAML,
    FRAMES_COLUMNS,
    FRAMES_CSV,
    MANIFEST_JSON,
    METADATA_CSV,
    RECORDING_JSON,
)
from air_sitl.errors import DatasetError
from air_sitl.files import decode_text
from air_sitl.state import Quat, Vec3

Image = npt.NDArray[np.uint8]


@dataclass(frozen=True, slots=True, kw_only=True)
class AirRow:
    """One ``metadata.csv`` row, typed; quaternions kept in the file's x, y, z, w order."""

    filename: str
    lat_deg: float
    lon_deg: float
    rel_alt_m: float
    imu_xyzw: Quat
    pose_enu_m: Vec3
    orientation_xyzw: Quat
    map_xy_px: tuple[int, int]
    svo_enu_m: Vec3


@dataclass(frozen=True, slots=True, kw_only=True)
class ArchiveFrame:
    """One frame of an archive: decoded image (BGR), metadata row, timestamp."""

    index: int
    timestamp_ns: int
    image: Image
    row: AirRow
    extra: dict[str, str] | None  # the frames.csv row of our archives, None for AIR's


def _num(text: str) -> float:
    t = text.strip().strip('"').strip()
    if t == "" or t.lower() in ("nan", "none", "null"):
        return math.nan
    return float(t)


def _int(text: str) -> int:
    t = text.strip().strip('"').strip()
    try:
        return int(t)
    except ValueError:
        return round(float(t))


def parse_air_row(fields: list[str], where: str) -> AirRow:
    """Type one row of 20 fields (DatasetError naming ``where`` on a bad value)."""
    if len(fields) != len(AIR_COLUMNS):
        msg = f"{where}: {len(fields)} fields, expected {len(AIR_COLUMNS)}"
        raise DatasetError(msg)
    try:
        v = [_num(x) for x in fields[1:15]]
        map_xy = (_int(fields[15]), _int(fields[16]))
        svo = (_num(fields[17]), _num(fields[18]), _num(fields[19]))
    except ValueError as err:
        msg = f"{where}: not a number ({err})"
        raise DatasetError(msg) from None
    return AirRow(
        filename=fields[0].strip().strip('"').strip(),
        lat_deg=v[0],
        lon_deg=v[1],
        rel_alt_m=v[2],
        imu_xyzw=(v[3], v[4], v[5], v[6]),
        pose_enu_m=(v[7], v[8], v[9]),
        orientation_xyzw=(v[10], v[11], v[12], v[13]),
        map_xy_px=map_xy,
        svo_enu_m=svo,
    )


class _Store:
    """Files of an archive: a folder or a zip (metadata.csv may sit in a sub-folder of it)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._zip: zipfile.ZipFile | None = None
        self._prefix = ""
        if path.is_dir():
            return
        if not path.exists():
            msg = f"{path}: no such archive (expected a folder or a .zip)"
            raise DatasetError(msg)
        try:
            self._zip = zipfile.ZipFile(path)
        except (zipfile.BadZipFile, OSError) as err:
            msg = f"{path}: not a folder or a readable zip archive ({err})"
            raise DatasetError(msg) from None
        candidates = [n for n in self._zip.namelist() if PurePosixPath(n).name == METADATA_CSV]
        if not candidates:
            msg = f"{path}: the zip holds no {METADATA_CSV}"
            raise DatasetError(msg)
        best = min(candidates, key=lambda n: (n.count("/"), n))
        parent = str(PurePosixPath(best).parent)
        self._prefix = "" if parent == "." else parent + "/"

    def exists(self, name: str) -> bool:
        if self._zip is None:
            return (self.path / name).is_file()
        try:
            self._zip.getinfo(self._prefix + name)
        except KeyError:
            return False
        return True

    def read(self, name: str) -> bytes:
        try:
            if self._zip is None:
                return (self.path / name).read_bytes()
            return self._zip.read(self._prefix + name)
        except (OSError, KeyError) as err:
            msg = f"{self.path}: cannot read {name} ({err})"
            raise DatasetError(msg) from None

    def names(self) -> list[str]:
        if self._zip is None:
            return sorted(
                p.relative_to(self.path).as_posix() for p in self.path.rglob("*") if p.is_file()
            )
        n = len(self._prefix)
        return sorted(x[n:] for x in self._zip.namelist() if x.startswith(self._prefix))

    @property
    def is_zip(self) -> bool:
        return self._zip is not None

    def close(self) -> None:
        if self._zip is not None:
            self._zip.close()


def _split_lines(data: bytes, where: str) -> tuple[list[list[str]], bool]:
    """CSV rows of ``data`` and whether its last line was torn (no newline at the end)."""
    text = decode_text(data, where, DatasetError)
    torn = bool(text) and not text.endswith("\n")
    if torn:
        text = text[: text.rfind("\n") + 1]
    return (list(csv.reader(io.StringIO(text))), torn)


class Archive(Closeable):
    """An opened archive: its rows, timestamps, manifest and camera; iterate for frames."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._store = _Store(path)
        if not self._store.exists(METADATA_CSV):
            self._store.close()
            msg = f"{path}: no {METADATA_CSV} (not an AIR archive)"
            raise DatasetError(msg)
        where = f"{path}/{METADATA_CSV}"
        table, self.torn_tail = _split_lines(self._store.read(METADATA_CSV), where)
        if not table:
            msg = f"{where}: empty file (expected the AIR header)"
            raise DatasetError(msg)
        self.header = [h.strip().strip('"') for h in table[0]]
        if tuple(self.header) != AIR_COLUMNS:
            msg = f"{where}: header {','.join(self.header)!r} is not the 20 AIR columns in order"
            raise DatasetError(msg)
        self.rows = [
            parse_air_row(fields, f"{where}: line {k}")
            for k, fields in enumerate(table[1:], start=2)
            if fields
        ]
        self.manifest: dict[str, Any] | None = self._json(MANIFEST_JSON)
        self.recording: dict[str, Any] | None = self._json(RECORDING_JSON)
        self.extra_rows: list[dict[str, str]] | None = None
        self.extra_torn_tail = False
        if self._store.exists(FRAMES_CSV):
            extra, self.extra_torn_tail = _split_lines(
                self._store.read(FRAMES_CSV), f"{path}/{FRAMES_CSV}"
            )
            # --nav ekf archives add the onboard estimate's columns after FRAMES_COLUMNS.
            if extra and tuple(extra[0][: len(FRAMES_COLUMNS)]) == FRAMES_COLUMNS:
                header = tuple(extra[0])
                self.extra_rows = [dict(zip(header, r, strict=False)) for r in extra[1:]]
        self.kind = "air-sitl" if self.extra_rows is not None else "air"

    def _json(self, name: str) -> dict[str, Any] | None:
        if not self._store.exists(name):
            return None
        try:
            value = json.loads(self._store.read(name).decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as err:
            msg = f"{self.path}/{name}: not readable JSON ({err})"
            raise DatasetError(msg) from None
        return value if isinstance(value, dict) else None

    @property
    def complete(self) -> bool:
        """True for a sealed archive of ours (manifest with ``complete: true``)."""
        return bool(self.manifest and self.manifest.get("complete") is True)

    def __len__(self) -> int:
        return len(self.rows)

    def timestamp_ns(self, index: int) -> int:
        """Simulation time of frame ``index`` (AIR archives: index x 20 ms)."""
        if self.extra_rows is not None and index < len(self.extra_rows):
            try:
                return int(self.extra_rows[index]["sim_time_ns"])
            except (KeyError, ValueError):
                pass
        return index * CAMERA_PERIOD_NS

    def exists(self, name: str) -> bool:
        """True when the archive holds the file ``name`` (relative to metadata.csv)."""
        return self._store.exists(name)

    def read_bytes(self, name: str) -> bytes:
        """The bytes of a file of the archive."""
        return self._store.read(name)

    def names(self) -> list[str]:
        """Every file of the archive, relative to the folder of metadata.csv."""
        return self._store.names()

    def jpeg(self, index: int) -> bytes:
        """The encoded image of frame ``index``."""
        return self._store.read(self.rows[index].filename)

    def image(self, index: int) -> Image:
        """The decoded image (BGR) of frame ``index``."""
        data = self.jpeg(index)
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)
        if image is None:
            msg = f"{self.path}/{self.rows[index].filename}: not a decodable image"
            raise DatasetError(msg)
        return np.asarray(image, dtype=np.uint8)

    def camera(self) -> dict[str, Any] | None:
        """``camera.yaml`` (ROS camera_info layout plus FOV and mounting), when present."""
        if not self._store.exists(CAMERA_YAML):
            return None
        value = yaml.safe_load(self._store.read(CAMERA_YAML).decode("utf-8"))
        return value if isinstance(value, dict) else None

    def frame(self, index: int) -> ArchiveFrame:
        """Frame ``index`` with its image decoded."""
        extra = None
        if self.extra_rows is not None and index < len(self.extra_rows):
            extra = self.extra_rows[index]
        return ArchiveFrame(
            index=index,
            timestamp_ns=self.timestamp_ns(index),
            image=self.image(index),
            row=self.rows[index],
            extra=extra,
        )

    def __iter__(self) -> Iterator[ArchiveFrame]:
        for index in range(len(self.rows)):
            yield self.frame(index)

    def close(self) -> None:
        """Close the zip file, if any."""
        self._store.close()


def open_archive(path: str | Path) -> Archive:
    """Open an archive folder or zip (ours or an original AIR one)."""
    return Archive(Path(path))
