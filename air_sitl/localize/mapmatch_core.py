"""Map matching without state: one frame against a reference orthophoto, around a prior.

The frame is rectified onto the reference map's own pixel grid at one pyramid level (the
inverse of :mod:`air_sitl.camera.render`: the homography image -> map pixels built from the
camera model, the AHRS attitude, the barometric height and the prior position), then
located in a window of the reference around the prior by **orientation correlation**: the
FFT cross-correlation of unit gradient vectors (gx + i gy) / |g| of both images, masked to
the frame's footprint. Orientation correlation ignores contrast and brightness, which is what
changes between two dates of a map (season, sun, construction), and its peak is sharp.
Measured on the AIR scenarios (frames of date 1 against date 0, ``benchmarks/bench_mapmatch.py``):
it separates right from wrong matches best of the four correlators tried (grey NCC, NCC of
gradient magnitude, complex gradient correlation, orientation correlation), at the same
accuracy, and costs three FFTs.

The match measures where the image centre ray meets the ground; with the attitude the
aircraft position follows, through the same homography (an attitude error of d radians moves
the fix by about height x d: the floor of this method, see :data:`ATTITUDE_SIGMA_RAD`).

Same inputs, same bits, wherever the arrays sit in memory: ``cv2.magnitude`` (its IPP path)
rounds differently with the alignment of its output buffer, which numpy places after whatever
was allocated before (in an online localizer: whatever its zenoh threads did meanwhile), so
the same frame gave fixes and covariances a few ppm apart from run to run and a lockstep
aided flight diverged. The gradient magnitude is therefore numpy's (correctly rounded
products, sum and square root); the other OpenCV calls here were measured alignment-proof.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.model import CameraModel
from air_sitl.frames import ned2geodetic, quat2matrix
from air_sitl.localize.decode import decode_gray
from air_sitl.maps.base import MapSource, map_px_jacobian
from air_sitl.state import GeoPoint, Quat

Image = npt.NDArray[np.uint8]
Mat3 = npt.NDArray[np.float64]

GSD_FACTOR = 4.0  # match at the level nearest 4x the frame's nadir ground sample distance
MAX_PATCH_PX = 192  # rectified patch side (level pixels) at most: the DFT stays at 256
MAX_PEAK_RATIO = 0.6  # refuse when the second peak is higher than this share of the first
MIN_RESPONSE = 0.15  # refuse when the peak's mean orientation agreement is below this
MIN_VALID_FRACTION = 0.25  # refuse when less of the patch holds ground (frame and map)
ATTITUDE_SIGMA_RAD = 0.008  # AHRS tilt error (typical of 0.002 noise + drift <= 0.02 rad)
PEAK_EXCLUSION_PX = 4  # the second peak is the best outside this radius of the first
_MIN_DOWN = 0.05  # a corner ray flatter than this (near the horizon): refuse the frame


@dataclass(frozen=True, slots=True, kw_only=True)
class MatchResult:
    """One match of a frame: the aircraft position it implies and how much to trust it."""

    east_m: float  # aircraft position implied by the match, ENU metres from home
    north_m: float
    shift_east_m: float  # the correction it makes to the prior
    shift_north_m: float
    peak_ratio: float  # best peak outside the main one / main peak (lower: more distinct)
    response: float  # main peak as the mean cosine of orientation differences (0..1; of
    # doubled orientation differences for the axial correlator)
    valid_fraction: float  # share of the patch that holds ground in both images
    level: int  # reference pyramid level matched at
    gsd_m: float  # metres per pixel of that level
    at_edge: bool  # the peak lies on the border of the search window (possibly truncated)
    accepted: bool  # passed the quality gate
    sigma_m: float  # 1-sigma horizontal uncertainty of the fix (per axis)

    @property
    def quality(self) -> float:
        """Confidence in [0, 1]: how far the peak ratio is below the refusal threshold."""
        if not self.accepted:
            return 0.0
        return max(0.0, min(1.0, 1.0 - self.peak_ratio / MAX_PEAK_RATIO)) * 0.5 + 0.5


def _orientation(gray: Image, valid: Image) -> npt.NDArray[np.float32]:
    """Unit gradient vectors of a grey image as a 2-channel (complex) float32 image, zero
    outside ``valid``."""
    gx = cv2.Sobel(gray, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(gray, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.sqrt(gx * gx + gy * gy)  # not cv2.magnitude: see the module docstring
    # A small floor keeps flat, noisy areas from voting with random orientations at full
    # weight, while any real edge counts as a unit vector whatever its contrast.
    inv = 1.0 / (mag + np.float32(2.0))
    inv[valid == 0] = 0.0
    return np.asarray(cv2.merge([gx * inv, gy * inv]), dtype=np.float32)


def _subpixel(a: float, b: float, c: float) -> float:
    d = a - 2.0 * b + c
    return 0.0 if d >= 0.0 else 0.5 * (a - c) / d


@dataclass(frozen=True, slots=True, kw_only=True)
class Rectified:
    """A frame rectified onto the reference grid and the reference window to search.

    Patch pixel (i, j) sits on reference-window pixel (i + margin, j + margin) when the prior
    is right; a score map has (2 margin + 1)^2 entries, one per integer shift.
    """

    patch: Image  # grey, level pixels
    patch_mask: Image  # 255 where the patch holds the frame (footprint, shrunk by 3 px)
    reference: Image  # grey window of the reference, the patch grown by margin_px per side
    reference_mask: Image  # 255 where the reference holds map pixels
    margin_px: int
    level: int
    gsd_m: float
    height_m: float
    prior_east_m: float
    prior_north_m: float


Scored = tuple[npt.NDArray[np.float32], float]  # score map, and its value at a perfect match


def orientation_correlation(rect: Rectified) -> Scored:
    """Cross-correlation of unit gradient orientations (3 FFTs): score map and normaliser."""
    a = _orientation(rect.patch, rect.patch_mask)
    b = _orientation(rect.reference, rect.reference_mask)
    return correlate(rect, a, b)


def correlate(rect: Rectified, a: npt.NDArray[np.float32], b: npt.NDArray[np.float32]) -> Scored:
    """The real part of the FFT cross-correlation of two 2-channel (complex) images, the
    patch's ``a`` over the reference window's ``b``, at every integer shift of the search
    window; the normaliser is the patch's footprint in pixels."""
    ph, pw = a.shape[:2]
    rh, rw = b.shape[:2]
    nh, nw = cv2.getOptimalDFTSize(rh), cv2.getOptimalDFTSize(rw)
    fa = cv2.dft(cv2.copyMakeBorder(a, 0, nh - ph, 0, nw - pw, cv2.BORDER_CONSTANT, value=0),
                 flags=cv2.DFT_COMPLEX_OUTPUT)  # fmt: skip
    fb = cv2.dft(cv2.copyMakeBorder(b, 0, nh - rh, 0, nw - rw, cv2.BORDER_CONSTANT, value=0),
                 flags=cv2.DFT_COMPLEX_OUTPUT)  # fmt: skip
    corr = cv2.idft(cv2.mulSpectrums(fb, fa, 0, conjB=True), flags=cv2.DFT_SCALE)
    m = 2 * rect.margin_px + 1
    score = np.ascontiguousarray(corr[:m, :m, 0], dtype=np.float32)
    return score, float(cv2.countNonZero(rect.patch_mask))


Correlator = Callable[[Rectified], Scored]


class MapMatcher:
    """Matches frames of one camera against one reference map (a date of it, or a GeoTIFF),
    with a correlator (default: orientation correlation) and its gate."""

    def __init__(
        self,
        reference: MapSource,
        camera: CameraModel,
        home: GeoPoint,
        *,
        gsd_factor: float = GSD_FACTOR,
        max_peak_ratio: float = MAX_PEAK_RATIO,
        min_response: float = MIN_RESPONSE,
        correlator: Correlator = orientation_correlation,
    ) -> None:
        self.map = reference
        self.camera = camera
        self.home = home
        self.gsd_factor = gsd_factor
        self.max_peak_ratio = max_peak_ratio
        self.min_response = min_response
        self.correlator = correlator
        self._c2b_kinv = camera.r_cam_to_body() @ np.linalg.inv(camera.intrinsics())
        # d(level-0 map px)/d(north, east) at home: UTM scale and grid convergence change by
        # about 1e-5 over a flight's few kilometres, far below a pixel over a footprint.
        a, b, c, d = map_px_jacobian(self.map, home.lat_deg, home.lon_deg)
        self._jac = np.array([[a, b], [c, d]])
        self._jac_inv = np.linalg.inv(self._jac)

    def map_px_of(self, east_m: float, north_m: float) -> tuple[float, float]:
        """Level-0 map pixel of a ground point given in ENU metres from home."""
        h = self.home
        lat, lon, _ = ned2geodetic(north_m, east_m, 0.0, h.lat_deg, h.lon_deg, h.alt_amsl_m)
        return self.map.latlon_to_map_px(lat, lon)

    def level_for_height(self, height_m: float) -> tuple[int, int]:
        """(pyramid level, JPEG reduction) used at a height above ground."""
        nadir_gsd = max(height_m, 1.0) / self.camera.fx_px
        level = self.map.level_for_gsd(nadir_gsd * self.gsd_factor)
        level_gsd = self.map.georef.gsd_m * (1 << level)
        reduce = 1
        while reduce < 8 and nadir_gsd * reduce * 2 <= level_gsd:
            reduce *= 2
        return level, reduce

    def homography(
        self, q_body_to_ned_wxyz: Quat, height_m: float, east_m: float, north_m: float
    ) -> Mat3:
        """Full-resolution image pixel -> level-0 map pixel, camera at (east, north, height)."""
        r = np.array(quat2matrix(q_body_to_ned_wxyz), dtype=np.float64) @ self._c2b_kinv
        to_ground = np.vstack([r[0] * height_m, r[1] * height_m, r[2]])  # -> (n, e, 1)
        x0, y0 = self.map_px_of(east_m, north_m)
        j = self._jac
        ground = np.array([[j[0, 0], j[0, 1], x0], [j[1, 0], j[1, 1], y0], [0.0, 0.0, 1.0]])
        out: Mat3 = ground @ to_ground
        return out

    def rectify(
        self,
        image: Image | bytes,
        q_body_to_ned_wxyz: Quat,
        height_m: float,
        prior_east_m: float,
        prior_north_m: float,
        radius_m: float,
    ) -> Rectified | None:
        """The frame on the reference grid around the prior, and the reference window to
        search; None when no footprint (below the ground, horizon in view)."""
        if not (height_m > 1.0 and math.isfinite(height_m)):
            return None
        level, reduce = self.level_for_height(height_m)
        s = 1 << level
        gsd = self.map.georef.gsd_m * s
        h0 = self.homography(q_body_to_ned_wxyz, height_m, prior_east_m, prior_north_m)
        # level-0 px -> level px: x_L = (x0 - (s - 1) / 2) / s
        off = (s - 1) / 2.0
        to_lvl = np.array([[1.0 / s, 0.0, -off / s], [0.0, 1.0 / s, -off / s], [0.0, 0.0, 1.0]])
        h_lvl = to_lvl @ h0
        cam = self.camera
        w1, hh1 = cam.width_px - 1.0, cam.height_px - 1.0
        corners = np.array([[0.0, 0.0, 1.0], [w1, 0.0, 1.0], [w1, hh1, 1.0], [0.0, hh1, 1.0]])
        # A corner ray pointing at or above the horizon: no usable footprint.
        rays = corners @ self._ray_rows(q_body_to_ned_wxyz).T
        if np.min(rays[:, 2] / np.linalg.norm(rays, axis=1)) < _MIN_DOWN:
            return None
        pc = corners @ h_lvl.T
        pc = pc[:, :2] / pc[:, 2:]
        centre = h_lvl @ np.array([cam.cx_px, cam.cy_px, 1.0])
        cx, cy = centre[0] / centre[2], centre[1] / centre[2]
        half = MAX_PATCH_PX // 2
        x0 = max(math.floor(pc[:, 0].min()), math.floor(cx) - half)
        y0 = max(math.floor(pc[:, 1].min()), math.floor(cy) - half)
        x1 = min(math.ceil(pc[:, 0].max()), math.floor(cx) + half)
        y1 = min(math.ceil(pc[:, 1].max()), math.floor(cy) + half)
        pw, ph = x1 - x0, y1 - y0
        if pw < 16 or ph < 16:
            return None
        # Image decoded at 1/reduce: its pixel (u', v') is full-resolution (r u' + (r-1)/2, ...)
        gray: Image
        if isinstance(image, bytes):
            gray = decode_gray(image, reduce)
            r = float(reduce)
        else:
            gray = image if image.ndim == 2 else np.asarray(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
            r = 1.0
        scale_in = np.array([[r, 0.0, (r - 1) / 2.0], [0.0, r, (r - 1) / 2.0], [0.0, 0.0, 1.0]])
        to_patch = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]])
        h_patch = to_patch @ h_lvl @ scale_in
        patch = cv2.warpPerspective(
            gray, h_patch, (pw, ph), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        pmask = np.zeros((ph, pw), np.uint8)
        poly = (pc - [x0, y0]).astype(np.float64)
        # shrink the footprint by 3 px towards its centre: no border gradients
        ctr = poly.mean(axis=0)
        d = poly - ctr
        n = np.linalg.norm(d, axis=1, keepdims=True)
        poly = ctr + d * np.maximum(n - 3.0, 0.0) / np.maximum(n, 1e-9)
        cv2.fillConvexPoly(pmask, np.round(poly).astype(np.int32), 255)
        margin = max(4, math.ceil(radius_m / gsd))
        ref = self.map.read_level(level, x0 - margin, y0 - margin, pw + 2 * margin, ph + 2 * margin)
        return Rectified(
            patch=np.asarray(patch, dtype=np.uint8),
            patch_mask=pmask,
            reference=np.asarray(cv2.cvtColor(ref, cv2.COLOR_BGRA2GRAY), dtype=np.uint8),
            reference_mask=np.asarray(
                cv2.erode(ref[:, :, 3], np.ones((5, 5), np.uint8)), dtype=np.uint8
            ),
            margin_px=margin,
            level=level,
            gsd_m=gsd,
            height_m=height_m,
            prior_east_m=prior_east_m,
            prior_north_m=prior_north_m,
        )

    def match(
        self,
        image: Image | bytes,
        q_body_to_ned_wxyz: Quat,
        height_m: float,
        prior_east_m: float,
        prior_north_m: float,
        radius_m: float,
    ) -> MatchResult | None:
        """Locate the frame within ``radius_m`` of the prior; None when it cannot be tried
        (below the ground, horizon in view)."""
        rect = self.rectify(
            image, q_body_to_ned_wxyz, height_m, prior_east_m, prior_north_m, radius_m
        )
        if rect is None:
            return None
        return self.locate(rect, self.correlator(rect))

    def locate(self, rect: Rectified, scored: Scored) -> MatchResult | None:
        """The best peak of a score map over the search window, its distinctness, the gate."""
        score, normaliser = scored
        margin = rect.margin_px
        ph, pw = rect.patch.shape
        _, vmax, _, (px, py) = cv2.minMaxLoc(score)
        if vmax <= 0 or normaliser <= 0:
            return None
        e = PEAK_EXCLUSION_PX
        masked = score.copy()
        masked[max(0, py - e) : py + e + 1, max(0, px - e) : px + e + 1] = -np.inf
        second = float(masked.max()) if masked.size > (2 * e + 1) ** 2 else 0.0
        ratio = max(0.0, second) / vmax
        fx = px + (_subpixel(score[py, px - 1], score[py, px], score[py, px + 1])
                   if 0 < px < score.shape[1] - 1 else 0.0)  # fmt: skip
        fy = py + (_subpixel(score[py - 1, px], score[py, px], score[py + 1, px])
                   if 0 < py < score.shape[0] - 1 else 0.0)  # fmt: skip
        at_edge = px in (0, score.shape[1] - 1) or py in (0, score.shape[0] - 1)
        # Overlap of the frame's footprint with map pixels at the found offset.
        ref_valid = rect.reference_mask[py : py + ph, px : px + pw]
        overlap = float(cv2.countNonZero(cv2.bitwise_and(rect.patch_mask, ref_valid)))
        valid_fraction = overlap / float(pw * ph)
        response = vmax / normaliser
        # Shift in level px -> level-0 px -> (north, east) metres.
        s = 1 << rect.level
        dx0, dy0 = (fx - margin) * s, (fy - margin) * s
        dn, de = self._jac_inv @ np.array([dx0, dy0])
        accepted = (
            ratio <= self.max_peak_ratio
            and response >= self.min_response
            and valid_fraction >= MIN_VALID_FRACTION
            and not at_edge
        )
        sigma = (0.5 * rect.gsd_m + ATTITUDE_SIGMA_RAD * rect.height_m) / max(0.2, 1.0 - ratio)
        return MatchResult(
            east_m=rect.prior_east_m + float(de),
            north_m=rect.prior_north_m + float(dn),
            shift_east_m=float(de),
            shift_north_m=float(dn),
            peak_ratio=ratio,
            response=response,
            valid_fraction=valid_fraction,
            level=rect.level,
            gsd_m=rect.gsd_m,
            at_edge=at_edge,
            accepted=accepted,
            sigma_m=sigma,
        )

    def _ray_rows(self, q: Quat) -> Mat3:
        return np.array(quat2matrix(q), dtype=np.float64) @ self._c2b_kinv
