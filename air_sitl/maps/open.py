"""Open a map from a ``--map`` value: ``urban``, ``forest``, ``farmland`` or GeoTIFF path(s).

GeoTIFF dates: ``--map a.tif,b.tif,c.tif`` lists the files of one area (date 0, 1, 2) and
``--map-date N`` picks one (default 0); ``--map-date other.tif`` names a date file directly.
Every date file must share the first file's CRS and contain home. Procedural maps take
``--map-date`` as an index (0, 1, 2), a season or an ISO label (see ``maps.procedural.DATES``).
"""

from __future__ import annotations

from pathlib import Path

from air_sitl.errors import MapError
from air_sitl.maps.base import MapSource
from air_sitl.maps.procedural import KINDS, ProceduralMap
from air_sitl.maps.procedural.surface import ProceduralSurface
from air_sitl.maps.surface import SurfaceModel
from air_sitl.state import GeoPoint

_TIFF_SUFFIXES = (".tif", ".tiff", ".gtiff")


def default_map_for_plan(plan_name: str) -> str:
    """AIR's naming: plans starting with U fly over ``urban``, F over ``forest``; ours
    starting with A (agricultural) over ``farmland``."""
    name = Path(plan_name).name.strip().upper()
    return "forest" if name.startswith("F") else "farmland" if name.startswith("A") else "urban"


def _looks_like_path(text: str) -> bool:
    return text.lower().endswith(_TIFF_SUFFIXES) or "/" in text or Path(text).exists()


def open_map(
    spec: str, home: GeoPoint, *, seed: int = 0, date: str | int | None = None
) -> MapSource:
    """The map named by ``spec`` at ``date``, placed so that ``home`` is inside it."""
    text = spec.strip()
    if text in KINDS:
        return ProceduralMap(text, home, seed=seed, date=date)
    files = [p.strip() for p in text.split(",") if p.strip()]
    if not files or not all(_looks_like_path(f) for f in files):
        msg = f"--map: {spec!r} is neither a procedural map ({', '.join(KINDS)}) nor a GeoTIFF path"
        raise MapError(msg)
    chosen = _choose_date(files, date)
    return _open_geotiff(Path(chosen), home, reference=Path(files[0]))


def _choose_date(files: list[str], date: str | int | None) -> str:
    if date is None:
        return files[0]
    text = str(date).strip()
    if text.isdigit():
        index = int(text)
        if index >= len(files):
            msg = f"--map-date {index}: the map has {len(files)} date file(s) (0..{len(files) - 1})"
            raise MapError(msg)
        return files[index]
    if _looks_like_path(text):
        return text
    msg = f"--map-date {text!r}: expected a date index (0, 1, ...) or a GeoTIFF path"
    raise MapError(msg)


def _open_geotiff(path: Path, home: GeoPoint, *, reference: Path) -> MapSource:
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
