"""Open a map from a ``--map`` value: ``urban``, ``forest``, ``farmland``, GeoTIFF path(s) or a
folder of dated GeoTIFFs.

GeoTIFF dates: ``--map a.tif,b.tif,c.tif`` lists the files of one area (date 0, 1, 2) and
``--map DIR`` takes every dated GeoTIFF of a folder (its TIFFTAG_DATETIME or ACQUISITION_DATE,
as ``map fetch`` and ``map make`` write them) in date order. ``--map-date`` picks one: its
index (default 0), its acquisition date (``2016-07-01``, or a year when one file has it) or a
file's path. Every date file must share the first file's CRS and contain home. Procedural maps
take ``--map-date`` as an index (0, 1, 2), a season or an ISO label of the world's dates
(``maps.procedural.dates_of``: ``DATES``, farmland ``FARMLAND_DATES``).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from air_sitl.errors import MapError
from air_sitl.maps.base import MapSource
from air_sitl.maps.procedural import KINDS, ProceduralMap
from air_sitl.maps.procedural.surface import ProceduralSurface
from air_sitl.maps.surface import SurfaceModel
from air_sitl.state import GeoPoint

if TYPE_CHECKING:
    from air_sitl.maps.geotiff import GeoTiffMap

_TIFF_SUFFIXES = (".tif", ".tiff", ".gtiff")


def default_map_for_plan(plan_name: str) -> str:
    """AIR's naming: plans starting with U fly over ``urban``, F over ``forest``; ours
    starting with A (agricultural) over ``farmland``."""
    name = Path(plan_name).name.strip().upper()
    return "forest" if name.startswith("F") else "farmland" if name.startswith("A") else "urban"


def _looks_like_path(text: str) -> bool:
    return text.lower().endswith(_TIFF_SUFFIXES) or "/" in text or Path(text).exists()


def open_map(
    spec: str,
    home: GeoPoint,
    *,
    seed: int = 0,
    date: str | int | None = None,
    shared_dir: Path | None = None,
) -> MapSource:
    """The map named by ``spec`` at ``date``, placed so that ``home`` is inside it
    (``shared_dir``: where a procedural map shares its drawn ground with other processes)."""
    text = spec.strip()
    if text in KINDS:
        return ProceduralMap(text, home, seed=seed, date=date, shared_dir=shared_dir)
    files = date_files(text)
    dates = _dates_of(files)
    index = _choose_date(files, dates, date)
    chosen = files[index] if isinstance(index, int) else index
    tif = _open_geotiff(Path(chosen), home, reference=Path(files[0]))
    tif.date_index = index if isinstance(index, int) else None
    tif.dates = tuple(dates)
    tif.spec = text
    return tif


def date_files(spec: str) -> list[str]:
    """The GeoTIFF files of a ``--map`` value, date 0 first (a folder: its dated GeoTIFFs in
    date order)."""
    text = spec.strip()
    if text and Path(text).is_dir():
        return _dated_folder(Path(text))
    files = [p.strip() for p in text.split(",") if p.strip()]
    if not files or not all(_looks_like_path(f) for f in files):
        msg = (
            f"--map: {spec!r} is neither a procedural map ({', '.join(KINDS)}), a GeoTIFF path "
            "nor a folder of dated GeoTIFFs"
        )
        raise MapError(msg)
    return files


def _dated_folder(folder: Path) -> list[str]:
    from air_sitl.maps.geotiff import read_acquisition_date  # rasterio: see _open_geotiff

    found = []
    for path in sorted(folder.iterdir()):
        name = path.name.lower()
        if name.startswith(".") or ".tmp." in name or not name.endswith(_TIFF_SUFFIXES):
            continue  # hidden, or a writer's temporary file left by a kill
        when = read_acquisition_date(path)
        if when is not None:
            found.append((when, path.name, str(path)))
    if not found:
        msg = (
            f"--map {folder}: no dated GeoTIFF in the folder (a date is a TIFFTAG_DATETIME or "
            "ACQUISITION_DATE tag, as map fetch and map make write)"
        )
        raise MapError(msg)
    return [path for _, _, path in sorted(found)]


def _dates_of(files: list[str]) -> list[str | None]:
    from air_sitl.maps.geotiff import read_acquisition_date  # rasterio: see _open_geotiff

    return [read_acquisition_date(Path(f)) for f in files]


def _choose_date(files: list[str], dates: list[str | None], date: str | int | None) -> int | str:
    """The index of the date file ``date`` names, or the path it names outside the list."""
    if date is None:
        return 0
    text = str(date).strip()
    if text.isdigit() and len(text) < 4:
        index = int(text)
        if index >= len(files):
            msg = f"--map-date {index}: the map has {len(files)} date file(s) (0..{len(files) - 1})"
            raise MapError(msg)
        return index
    if re.fullmatch(r"\d{4}(-\d{2}-\d{2})?", text):
        hits = [i for i, d in enumerate(dates) if d is not None and d.startswith(text)]
        if len(hits) == 1:
            return hits[0]
        known = ", ".join(f"{i}={d}" for i, d in enumerate(dates) if d) or "none dated"
        many = f"{len(hits)} files have it" if hits else "no file has it"
        msg = f"--map-date {text}: {many} (dates of the map: {known})"
        raise MapError(msg)
    if _looks_like_path(text):
        return files.index(text) if text in files else text
    msg = f"--map-date {text!r}: expected a date index (0, 1, ...), a date (YYYY-MM-DD) or a path"
    raise MapError(msg)


def _open_geotiff(path: Path, home: GeoPoint, *, reference: Path) -> GeoTiffMap:
    # Here, not at the top: rasterio (GDAL) takes about half a second to import, and only
    # GeoTIFF maps need it (procedural maps and every other command start without it).
    from air_sitl.maps.geotiff import GeoTiffMap

    tif = GeoTiffMap(path, ground_elevation_m=home.alt_amsl_m)
    if reference != path:
        ref = GeoTiffMap(reference, ground_elevation_m=home.alt_amsl_m)
        try:
            if ref.georef.crs != tif.georef.crs:
                msg = (
                    f"{path}: CRS {tif.georef.crs} differs from {reference} "
                    f"({ref.georef.crs}); dates of one map must share it"
                )
                raise MapError(msg)
        finally:
            ref.close()
    x, y = tif.latlon_to_map_px(home.lat_deg, home.lon_deg)
    w, h = tif.georef.width_px or 0, tif.georef.height_px or 0
    if not (-0.5 <= x < w - 0.5 and -0.5 <= y < h - 0.5):
        tif.close()
        msg = (
            f"{path}: home ({home.lat_deg:.6f}, {home.lon_deg:.6f}) is outside the map "
            f"(at pixel {x:.0f}, {y:.0f} of {w}x{h})"
        )
        raise MapError(msg)
    return tif


def open_surface(dem: str | None, map_source: MapSource) -> SurfaceModel | None:
    """The surface model of ``--dem`` over a map: a GeoTIFF DEM, ``builtin`` or None (flat)."""
    if dem is None or not dem.strip():
        return None
    text = dem.strip()
    if text == "builtin":
        if not isinstance(map_source, ProceduralMap):
            msg = f"--dem builtin: only the procedural maps ({', '.join(KINDS)}) have one"
            raise MapError(msg)
        return ProceduralSurface(map_source)
    from air_sitl.maps.geotiff import GeoTiffDem  # rasterio: see _open_geotiff

    return GeoTiffDem(Path(text), map_source)
