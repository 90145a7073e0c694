"""Drawing in world metres onto one tile, and the look of each map date.

World coordinates are UTM metres (E east, N north); the tile's first pixel centre is at the
absolute lattice position (x0, y0): pixel centre (col, row) is at E = (x0 + col + 0.5) * gsd,
N = -(y0 + row + 0.5) * gsd. Drawing uses OpenCV with 4 fractional bits and anti-aliasing.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural.noise import FloatImage
from air_sitl.maps.procedural.sun import sun_position

_SHIFT = 4
_ONE = 1 << _SHIFT

Color = tuple[float, float, float]  # BGR 0..255
Paint = Color | tuple[float]  # a colour, or one value on a mask layer
Point = tuple[float, float]  # (E, N) metres
DEFAULT_LAT_DEG = 47.4  # the default home (PX4 SITL, Zurich)


@dataclass(frozen=True, slots=True)
class DateLook:
    """One date of a procedural map: an aerial survey flown on ``label`` at ``solar_time``
    (local solar time), its season, and the sun it saw from latitude ``lat_deg``."""

    index: int
    label: str  # ISO date of the acquisition
    season: str  # "summer", "autumn", "spring"
    sun_azimuth_deg: float  # clockwise from north
    sun_elevation_deg: float
    solar_time: str = "12:00"  # HH:MM local solar time of the survey
    lat_deg: float = DEFAULT_LAT_DEG  # where the sun was computed

    @property
    def full_label(self) -> str:
        """``2009-06-20 10:40`` (date and local solar time)."""
        return f"{self.label} {self.solar_time}"

    @property
    def leaf_off(self) -> bool:
        """Whether deciduous trees stand bare (the spring survey, before leaf-out)."""
        return self.season == "spring"

    def at_latitude(self, lat_deg: float) -> DateLook:
        """The same survey seen from another latitude (the map's): the sun moves."""
        return survey_date(self.index, self.label, self.season, self.solar_time, lat_deg)

    def shadow_vector(self, height_m: float) -> Point:
        """(dE, dN) of the shadow cast by a point ``height_m`` above the ground."""
        length = height_m / math.tan(math.radians(max(self.sun_elevation_deg, 5.0)))
        az = math.radians(self.sun_azimuth_deg)
        return (-math.sin(az) * length, -math.cos(az) * length)

    def sun_dir(self) -> Point:
        """Horizontal unit vector (E, N) toward the sun."""
        az = math.radians(self.sun_azimuth_deg)
        return (math.sin(az), math.cos(az))


def survey_date(index: int, label: str, season: str, solar_time: str, lat_deg: float) -> DateLook:
    """A date whose sun follows from its day, its solar time and the latitude."""
    hh, mm = solar_time.split(":")
    az, el = sun_position(label, int(hh) + int(mm) / 60.0, lat_deg)
    return DateLook(index, label, season, az, el, solar_time, lat_deg)


# The three surveys (sun at the default home's latitude; maps move it to their own).
DATES: tuple[DateLook, ...] = (
    survey_date(0, "2009-06-20", "summer", "10:40", DEFAULT_LAT_DEG),
    survey_date(1, "2012-10-08", "autumn", "13:40", DEFAULT_LAT_DEG),
    survey_date(2, "2016-04-22", "spring", "15:30", DEFAULT_LAT_DEG),
)
# The farmland world's surveys, as NAIP flies farmland: in the growing season (June-August,
# leaf-on), 3 and 7 years after the reference (the common June survey).
FARMLAND_DATES: tuple[DateLook, ...] = (
    DATES[0],
    survey_date(1, "2012-07-24", "summer", "11:20", DEFAULT_LAT_DEG),
    survey_date(2, "2016-08-13", "summer", "12:50", DEFAULT_LAT_DEG),
)


def dates_of(kind: str | None) -> tuple[DateLook, ...]:
    """The survey dates of a procedural world (``farmland`` its own, the others ``DATES``)."""
    return FARMLAND_DATES if kind == "farmland" else DATES


class Canvas:
    """One tile being drawn: colour image, shadow mask and vegetation mask."""

    def __init__(self, x0: int, y0: int, size: int, gsd_m: float, background: Color) -> None:
        self.x0 = x0
        self.y0 = y0
        self.size = size
        self.gsd_m = gsd_m
        self.img = np.empty((size, size, 3), dtype=np.uint8)
        self.img[:] = background
        self.shadow = np.zeros((size, size), dtype=np.uint8)
        self.veg = np.zeros((size, size), dtype=np.uint8)
        # World bounds of the tile (metres).
        self.e_min = x0 * gsd_m
        self.e_max = (x0 + size) * gsd_m
        self.n_max = -y0 * gsd_m
        self.n_min = -(y0 + size) * gsd_m

    def px(self, pts: Sequence[Point]) -> npt.NDArray[np.int32]:
        """World points to fixed-point pixel coordinates for OpenCV."""
        return np.array(self._px(pts), dtype=np.int32)

    def _px(self, pts: Sequence[Point]) -> list[tuple[int, int]]:
        k = _ONE / self.gsd_m
        ox = (0.5 + self.x0) * _ONE
        oy = (0.5 + self.y0) * _ONE
        return [(round(e * k - ox), round(-n * k - oy)) for e, n in pts]

    def visible(self, p: Sequence[tuple[int, int]], pad_px: float = 2.0) -> bool:
        """Whether fixed-point pixels p come near the tile (cheap culling before drawing)."""
        lim = (self.size + pad_px) * _ONE
        lo = -pad_px * _ONE
        xs = [q[0] for q in p]
        ys = [q[1] for q in p]
        return not (max(xs) < lo or min(xs) > lim or max(ys) < lo or min(ys) > lim)

    def overlaps(self, e0: float, n0: float, e1: float, n1: float, margin_m: float) -> bool:
        """Whether a world box comes within ``margin_m`` of the tile."""
        return not (
            e1 < self.e_min - margin_m
            or e0 > self.e_max + margin_m
            or n1 < self.n_min - margin_m
            or n0 > self.n_max + margin_m
        )

    def poly(self, pts: Sequence[Point], color: Paint, layer: str = "img") -> None:
        """Fill a polygon on a layer ("img", "shadow", "veg")."""
        p = self._px(pts)
        if not self.visible(p):
            return
        target = getattr(self, layer)
        col = color if layer == "img" else (color[0],)
        cv2.fillPoly(target, [np.array(p, dtype=np.int32)], col, cv2.LINE_AA, _SHIFT)

    def circle(self, c: Point, r_m: float, color: Paint, layer: str = "img") -> None:
        """Fill a disc."""
        k = _ONE / self.gsd_m
        px = round(c[0] * k - (0.5 + self.x0) * _ONE)
        py = round(-c[1] * k - (0.5 + self.y0) * _ONE)
        r = round(r_m * k)
        lim = self.size * _ONE + r
        if px < -r or py < -r or px > lim or py > lim:
            return
        target = getattr(self, layer)
        col = color if layer == "img" else (color[0],)
        p = (px, py)
        cv2.circle(target, (int(p[0]), int(p[1])), max(r, 1), col, -1, cv2.LINE_AA, _SHIFT)

    def line(self, pts: Sequence[Point], color: Color, width_m: float) -> None:
        """A polyline of a given width in metres (thin lines become 1 px, anti-aliased)."""
        if width_m < 0.2 * self.gsd_m:
            return  # far thinner than a pixel: averages out (direct coarse levels)
        thick = max(1, round(width_m / self.gsd_m))
        p = self._px(pts)
        if self.visible(p, thick):
            cv2.polylines(
                self.img, [np.array(p, dtype=np.int32)], False, color, thick, cv2.LINE_AA, _SHIFT
            )

    def segments(self, segs: Sequence[tuple[Point, Point]], color: Color, width_m: float) -> None:
        """Many separate two-point lines in one call (dashes, stall lines)."""
        if not segs or width_m < 0.2 * self.gsd_m:
            return
        thick = max(1, round(width_m / self.gsd_m))
        flat = self._px([p for seg in segs for p in seg])
        keep = [
            np.array(flat[i : i + 2], dtype=np.int32)
            for i in range(0, len(flat), 2)
            if self.visible(flat[i : i + 2], thick)
        ]
        if keep:
            cv2.polylines(self.img, keep, False, color, thick, cv2.LINE_AA, _SHIFT)


def rect(cx: float, cy: float, hw: float, hh: float, c: float, s: float) -> list[Point]:
    """Corners of a rectangle centred at (cx, cy) (layout frame) rotated by (c, s)."""
    pts = ((-hw, -hh), (hw, -hh), (hw, hh), (-hw, hh))
    return [(cx + c * x - s * y, cy + s * x + c * y) for x, y in pts]


def shade(color: Color, factor: float) -> Color:
    """Scale a colour, clipped to 0..255."""
    return (
        min(255.0, color[0] * factor),
        min(255.0, color[1] * factor),
        min(255.0, color[2] * factor),
    )


def finish(
    canvas: Canvas,
    texture: FloatImage,
    grain: FloatImage,
    shadow_strength: float,
    veg_texture: FloatImage | None,
) -> npt.NDArray[np.uint8]:
    """Combine colour, texture, vegetation detail and shadows into the final BGR tile."""
    gain = 1.0 + texture
    if veg_texture is not None:
        veg = canvas.veg.astype(np.float32) * np.float32(1.0 / 255.0)
        gain += veg * veg_texture
    if shadow_strength > 0:
        gain *= 1.0 - canvas.shadow.astype(np.float32) * np.float32(shadow_strength / 255.0)
    out = canvas.img.astype(np.float32) * gain[:, :, None] + grain[:, :, None]
    return np.clip(out, 0, 255).astype(np.uint8)
