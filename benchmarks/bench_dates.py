"""How different the dates of a procedural map are, against real imagery of different years.

    python benchmarks/bench_dates.py [--crops 48] [--seed 0] [--maps urban,forest]
        [--real A_DIR B_DIR] [--real-tifs A.tif B.tif] [--frames 20] [--sheet OUT.png]
        [--heights 200,300,3000]

For each procedural map, random 256 x 256 crops at 0.5 m per pixel of date 0 against the same
place at date 1 and date 2 (and date 0 against itself: the same-date check), in grey:

- ``ncc``: zero-mean normalised cross-correlation of the two crops (median over crops);
- ``reg``: template registration success: the central 128 x 128 of B moved by a known random
  offset of up to 40 px is found in A with OpenCV ``matchTemplate`` (TM_CCOEFF_NORMED);
  success = the peak within 3 px of the truth;
- ``reg8``, ``peak``: the same registration within 8 px (the surveys' misregistration is
  tolerated) and its median peak correlation;
- ``oc1``, ``oc2``, ``flip``: at 2 m pixels, the single- and doubled-angle gradient
  orientation agreement of A and B, and the share of textured 32 m windows whose single-angle
  agreement is below 0 (contrast inverted, or unrelated content);
- ``tex1``, ``tex2``: how much of the materials' texture two dates share: the NCC of the
  band-passed pair (1-6 m and 3-12 m) in windows without edges (16 and 32 m; the median
  over all such windows of the row);
- ``sat``: mean HSV saturation (OpenCV's 0..255) of the B crops;
- ``slope``: radially averaged power-spectrum slope of the B crops (grey, Hann window, 4-100
  cycles per 256 px, least squares in log-log), the median over crops.

Urban crops are also reported by where they fall (``urban built``, ``urban fields``: most of
the crop in blocks of the town or of its outskirts' farm fields), to set beside real suburbs
(LEVIR) and real farmland (DSIFN).

``--real A_DIR B_DIR``: the same figures for pairs of images with the same file names in two
folders (public change-detection samples: A the earlier year, B the later); images larger than
256 px give several crops. Targets (issues 24 and 32) are printed beside.

Matcher figure (``--frames N``, default 20; 0 skips it): N frames per world, date and height
(200, 300, 3000 m; random places, headings, roll and pitch up to 5 degrees) rendered from date
k and matched against date 0 by the mapmatch baseline's matcher from a prior 10-30 m off:
share accepted within 5 m and the median response. ``--real-tifs A.tif B.tif``: the same for
two real GeoTIFFs of one place (frames of B against A; and A against itself). ``--heights``:
the matcher's heights above ground (a 5 m NAIP quarter quad, 4.67 x 3.6 km, holds frames up
to about 2000 m with their search).
``--sheet`` saves crops of dates 0/1/2 of each map side by side with real pairs, to look
at. Deterministic with ``--seed``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import ned2geodetic
from air_sitl.localize.mapmatch_core import MapMatcher
from air_sitl.maps.base import MapSource
from air_sitl.maps.procedural import KINDS, ProceduralMap
from air_sitl.maps.procedural.canvas import dates_of
from air_sitl.maps.procedural.urban import UrbanWorld
from air_sitl.state import GeoPoint

CROP = 256
TEMPLATE = 128
MAX_OFFSET = 40
HIT_PX = 3.0
HIT8_PX = 8.0  # tolerates the surveys' 1-3 px misregistration (issue 32)
MATCH_SCALE = 4  # gradient statistics at 2 m pixels (the scale the map matcher sees)
WIN_PX = 16  # ... in 32 m windows
GSD_M = 0.5
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
SPREAD_PX = 12_000  # crops are taken within 6 km of home
# Issue 24's targets (date 0 vs 2, urban and forest) and what real pairs measured.
TARGETS = {
    "ncc": (0.15, 0.50),
    "reg": (0.15, 0.70),
    "same": (1.0, 1.0),
    "sat": (30.0, 70.0),
    "slope": (-2.50, -1.95),  # real 0.5 m crops of one date measure -2.43 (issue 32)
    # issue 32 (date 0 vs 2): registration within 8 px and its median peak; the matcher's
    # acceptance within 5 m at 200-300 m and at 3000 m; the same date at least 95 %.
    "reg8": (0.25, 0.70),
    "peak": (0.20, 0.45),
    "accept_low": (0.30, 0.90),
    "accept_high": (0.0, 0.70),
    "accept_same": (0.95, 1.0),
}
HEIGHTS_M = (200.0, 300.0, 3000.0)
PRIOR_OFF_M = (10.0, 30.0)  # the prior is this far off the truth, in a random direction
SEARCH_RADIUS_M = 45.0  # around the prior (the localizer's 3 sigma + 5 m for such a prior)
RIGHT_M = 5.0
TILT_DEG = 5.0  # roll and pitch up to this
FRAME_SPREAD_M = 2500.0  # procedural frames within this of home (east and north)

Gray = npt.NDArray[np.float32]
Bgr = npt.NDArray[np.uint8]


def gray(bgr: Bgr) -> Gray:
    """Grey float32 image of a BGR one."""
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)


def ncc(a: Gray, b: Gray) -> float:
    """Zero-mean normalised cross-correlation of two same-size images."""
    da, db = a - a.mean(), b - b.mean()
    den = float(np.sqrt((da * da).sum() * (db * db).sum()))
    return float((da * db).sum() / den) if den > 0 else 0.0


def registers(a: Gray, b: Gray, rng: np.random.Generator) -> tuple[float, float]:
    """B's central template moved by a random offset, found in A: (error px, peak)."""
    dx, dy = (int(v) for v in rng.integers(-MAX_OFFSET, MAX_OFFSET + 1, size=2))
    c = (CROP - TEMPLATE) // 2
    tpl = b[c + dy : c + dy + TEMPLATE, c + dx : c + dx + TEMPLATE]
    res = cv2.matchTemplate(a, tpl, cv2.TM_CCOEFF_NORMED)
    _, peak, _, (mx, my) = cv2.minMaxLoc(res)
    return float(np.hypot(mx - (c + dx), my - (c + dy))), float(peak)


def gradient_agreement(a: Gray, b: Gray) -> tuple[float, float, float]:
    """At 2 m pixels: (single-angle, doubled-angle) orientation agreement of A and B (mean
    cosine of the gradient angle difference, and of twice it, weighted by |gA| |gB|), and the
    share of textured 32 m windows whose single-angle agreement is below 0 (gradients
    flipped: contrast inverted, or unrelated content)."""
    size = (a.shape[1] // MATCH_SCALE, a.shape[0] // MATCH_SCALE)
    sa = cv2.resize(a, size, interpolation=cv2.INTER_AREA)
    sb = cv2.resize(b, size, interpolation=cv2.INTER_AREA)
    ax, ay = cv2.Sobel(sa, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(sa, cv2.CV_32F, 0, 1, ksize=3)
    bx, by = cv2.Sobel(sb, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(sb, cv2.CV_32F, 0, 1, ksize=3)
    w = np.hypot(ax, ay) * np.hypot(bx, by)
    c1 = ax * bx + ay * by
    s1 = ay * bx - ax * by
    c2 = (c1 * c1 - s1 * s1) / np.maximum(w, 1e-6)
    flipped, windows = 0, 0
    n = size[0] // WIN_PX
    for i in range(n):
        for j in range(n):
            win = np.s_[i * WIN_PX : (i + 1) * WIN_PX, j * WIN_PX : (j + 1) * WIN_PX]
            if min(float(sa[win].std()), float(sb[win].std())) <= 6.0:
                continue  # flat in one of them: no gradients to compare
            windows += 1
            flipped += float(c1[win].sum()) < 0.0
    total = max(float(w.sum()), 1e-6)
    share = flipped / windows if windows else 0.0
    return float(c1.sum()) / total, float(c2.sum()) / total, share


TEXTURE_BANDS_M = ((1.0, 6.0, 16.0), (3.0, 12.0, 32.0))  # (fine sigma, coarse sigma, window)
EDGE_FREE_DN = 45.0  # a window without edges: its smoothed grey spans less than this
TEXTURED_DN = 1.0  # ... and its band-passed texture has at least this std in both images


def texture_windows(a: Gray, b: Gray, gsd_m: float) -> tuple[list[float], list[float]]:
    """NCC of the band-passed A and B in each window without edges, per band (fine, coarse):
    how much of the texture of grass, fields, asphalt and roofs two dates share."""
    out: tuple[list[float], list[float]] = ([], [])
    for (lo_m, hi_m, win_m), vals in zip(TEXTURE_BANDS_M, out, strict=True):
        ba = cv2.GaussianBlur(a, (0, 0), lo_m / gsd_m) - cv2.GaussianBlur(a, (0, 0), hi_m / gsd_m)
        bb = cv2.GaussianBlur(b, (0, 0), lo_m / gsd_m) - cv2.GaussianBlur(b, (0, 0), hi_m / gsd_m)
        sa = cv2.GaussianBlur(a, (0, 0), 2.0 * lo_m / gsd_m)
        sb = cv2.GaussianBlur(b, (0, 0), 2.0 * lo_m / gsd_m)
        w = round(win_m / gsd_m)
        for y in range(0, a.shape[0] - w + 1, w):
            for x in range(0, a.shape[1] - w + 1, w):
                win = np.s_[y : y + w, x : x + w]
                if max(float(np.ptp(sa[win])), float(np.ptp(sb[win]))) > EDGE_FREE_DN:
                    continue
                if min(float(ba[win].std()), float(bb[win].std())) < TEXTURED_DN:
                    continue
                vals.append(ncc(ba[win], bb[win]))
    return out


def saturation(bgr: Bgr) -> float:
    """Mean HSV saturation (0..255)."""
    return float(cv2.cvtColor(bgr, cv2.COLOR_BGR2HSV)[:, :, 1].mean())


def spectrum_slope(g: Gray) -> float:
    """Slope of the radially averaged power spectrum, 4-100 cycles per 256 px, log-log."""
    n = g.shape[0]
    win = np.outer(np.hanning(n), np.hanning(n)).astype(np.float32)
    power = np.abs(np.fft.fftshift(np.fft.fft2((g - g.mean()) * win))) ** 2
    yy, xx = np.indices(power.shape)
    r = np.hypot(xx - n // 2, yy - n // 2).round().astype(np.int64)
    radial = np.bincount(r.ravel(), power.ravel()) / np.maximum(np.bincount(r.ravel()), 1)
    f = np.arange(4, 101) * (n / CROP)
    sel = np.round(f).astype(np.int64)
    slope = np.polyfit(np.log10(f), np.log10(radial[sel] + 1e-12), 1)[0]
    return float(slope)


class Figures:
    """The figures of one row: pairs of crops (A, B) and the registration draws."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.nccs: list[float] = []
        self.hits: list[bool] = []
        self.hits8: list[bool] = []
        self.peaks: list[float] = []
        self.oc1: list[float] = []
        self.oc2: list[float] = []
        self.flipped: list[float] = []
        self.sats: list[float] = []
        self.slopes: list[float] = []
        self.tex: tuple[list[float], list[float]] = ([], [])

    def add(self, a: Bgr, b: Bgr, rng: np.random.Generator, gsd_m: float = GSD_M) -> None:
        ga, gb = gray(a), gray(b)
        self.nccs.append(ncc(ga, gb))
        err, peak = registers(ga, gb, rng)
        self.hits.append(err <= HIT_PX)
        self.hits8.append(err <= HIT8_PX)
        self.peaks.append(peak)
        oc1, oc2, flipped = gradient_agreement(ga, gb)
        self.oc1.append(oc1)
        self.oc2.append(oc2)
        self.flipped.append(flipped)
        self.sats.append(saturation(b))
        self.slopes.append(spectrum_slope(gb))
        for vals, new in zip(self.tex, texture_windows(ga, gb, gsd_m), strict=True):
            vals.extend(new)

    def row(self) -> dict[str, float]:
        return {
            "ncc": float(np.median(self.nccs)),
            "reg": float(np.mean(self.hits)),
            "reg8": float(np.mean(self.hits8)),
            "peak": float(np.median(self.peaks)),
            "oc1": float(np.median(self.oc1)),
            "oc2": float(np.median(self.oc2)),
            "flip": float(np.mean(self.flipped)),
            "sat": float(np.mean(self.sats)),
            "slope": float(np.median(self.slopes)),
            "tex1": float(np.median(self.tex[0])) if self.tex[0] else float("nan"),
            "tex2": float(np.median(self.tex[1])) if self.tex[1] else float("nan"),
            "n": float(len(self.nccs)),
        }


def procedural_rows(
    kind: str,
    crops: int,
    seed: int,
    map_seed: int,
    keep: list[list[Bgr]] | None,
    by_place: bool = False,
) -> list[tuple[str, dict[str, float]]]:
    """Rows ``kind 0-0``, ``kind 0-1``, ``kind 0-2`` over the same random places; with
    ``by_place``, urban's also for its built-up and its fields' crops."""
    maps = [ProceduralMap(kind, HOME, seed=map_seed, date=d, gsd_m=GSD_M) for d in (0, 1, 2)]
    ox, oy = maps[0].origin_abs_px
    rng = np.random.default_rng([seed, KINDS.index(kind) + 1])
    places = rng.integers(-SPREAD_PX // 2, SPREAD_PX // 2, size=(crops, 2))
    figs = {d: Figures(f"{kind} 0-{d}") for d in (0, 1, 2)}
    reg_rngs = {d: np.random.default_rng([seed, 7, d]) for d in (0, 1, 2)}
    # Urban crops also by where they fall: the town's outskirts (fields) or built-up.
    parts: dict[str, dict[int, Figures]] = {"built": {}, "fields": {}}
    part_rngs = {d: np.random.default_rng([seed, 17, d]) for d in (1, 2)}
    world = UrbanWorld(map_seed) if by_place and kind == "urban" else None
    kept: set[str] = set()
    for i, (px, py) in enumerate(places):
        x0, y0 = ox + 5120 + int(px), oy + 5120 + int(py)
        imgs = [m.render_abs(x0, y0, CROP) for m in maps]
        for d in (0, 1, 2):
            figs[d].add(imgs[0], imgs[d], reg_rngs[d])
        fields = world is not None and in_fields(world, x0, y0)
        if world is not None:
            part = parts["fields" if fields else "built"]
            for d in (1, 2):
                part.setdefault(d, Figures("")).add(imgs[0], imgs[d], part_rngs[d])
        # The sheet: each world's first crop, and urban's first on the outskirts' fields.
        if keep is not None and (i == 0 or (fields and "fields" not in kept)):
            keep.append(imgs)
            kept.add("fields" if fields else "first")
    rows = [(f"{kind} 0-{d}" + (" (same)" if d == 0 else ""), figs[d].row()) for d in (0, 1, 2)]
    return rows + [(f"{kind} {n} 0-{d}", f.row()) for n, fs in parts.items() for d, f in fs.items()]


def in_fields(world: UrbanWorld, x0: int, y0: int) -> bool:
    """Whether most of an urban crop (absolute 0.5 m pixels) lies in the outskirts' fields."""
    pts = [(x0 + 16 + 32 * i, y0 + 16 + 32 * j) for i in range(8) for j in range(8)]
    return sum(world.in_fields(x * GSD_M, -y * GSD_M) for x, y in pts) >= len(pts) // 2


def matcher_figure(
    reference: MapSource,
    frames: MapSource,
    home: GeoPoint,
    height_m: float,
    count: int,
    rng: np.random.Generator,
    spread_m: float,
) -> tuple[float, float]:
    """Frames of ``frames`` at ``height_m`` (random places within ``spread_m`` of home, random
    headings, roll and pitch up to 5 degrees) matched against ``reference`` by the mapmatch
    baseline's matcher from a prior 10-30 m off: (share accepted within 5 m, median
    response; 0 where the matcher could not try)."""
    camera = CameraModel()
    renderer = Renderer(frames, camera, seed=int(rng.integers(1 << 30)))
    matcher = MapMatcher(reference, camera, home)
    right, responses = 0, []
    for i in range(count):
        east, north = (float(v) for v in rng.uniform(-spread_m, spread_m, size=2))
        roll, pitch = (float(v) for v in np.radians(rng.uniform(-TILT_DEG, TILT_DEG, size=2)))
        yaw = float(rng.uniform(-np.pi, np.pi))
        lat, lon, _ = ned2geodetic(north, east, 0.0, home.lat_deg, home.lon_deg, home.alt_amsl_m)
        state = pose_state(lat, lon, home.alt_amsl_m + height_m, alt_agl_m=height_m,
                           roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw)  # fmt: skip
        jpeg, _ = renderer.frame_jpeg(state, i, warn=False)
        off, ang = float(rng.uniform(*PRIOR_OFF_M)), float(rng.uniform(0.0, 2.0 * np.pi))
        prior_e, prior_n = east + off * np.cos(ang), north + off * np.sin(ang)
        res = matcher.match(
            jpeg, state.q_body_to_ned_wxyz, height_m, prior_e, prior_n, SEARCH_RADIUS_M
        )
        responses.append(0.0 if res is None else res.response)
        if res is not None and res.accepted:
            right += bool(np.hypot(res.east_m - east, res.north_m - north) < RIGHT_M)
    return right / max(count, 1), float(np.median(responses)) if responses else 0.0


def matcher_rows(
    kind: str, count: int, seed: int, map_seed: int, heights: tuple[float, ...] = HEIGHTS_M
) -> list[tuple[str, dict[str, float]]]:
    """Rows ``kind 0-d @h``: frames of date d at each height matched against date 0. Every
    date is flown at the same places, headings and priors (a paired comparison of the
    gaps; the reference's tiles are drawn once)."""
    ref = ProceduralMap(kind, HOME, seed=map_seed, date=0)
    rows = []
    for d in (0, 1, 2):
        frames = ref if d == 0 else ProceduralMap(kind, HOME, seed=map_seed, date=d)
        for h in heights:
            rng = np.random.default_rng([seed, 11, KINDS.index(kind), int(h)])
            acc, resp = matcher_figure(ref, frames, HOME, h, count, rng, FRAME_SPREAD_M)
            rows.append((f"{kind} 0-{d} @{h:.0f} m", {"accept": acc, "response": resp, "n": count}))
    return rows


def real_tif_rows(
    a_path: Path, b_path: Path, count: int, seed: int, heights: tuple[float, ...] = HEIGHTS_M
) -> list[tuple[str, dict[str, float]]]:
    """Rows ``real A-B @h`` and ``real A-A @h``: frames of GeoTIFF B (the later date) matched
    against GeoTIFF A around A's centre; heights whose frames do not fit in A are skipped."""
    from rasterio.warp import transform  # GDAL: imported only when real GeoTIFFs are given

    from air_sitl.maps.geotiff import GeoTiffMap

    for path in (a_path, b_path):
        if not path.is_file():
            sys.exit(f"--real-tifs: {path}: no such file")
    a = GeoTiffMap(a_path, ground_elevation_m=0.0)
    b = GeoTiffMap(b_path, ground_elevation_m=0.0)
    w, h = a.georef.width_px or 0, a.georef.height_px or 0
    cx, cy = a.georef.px_to_crs(w / 2.0, h / 2.0)
    lon, lat = transform(a.georef.crs, "EPSG:4326", [cx], [cy])
    home = GeoPoint(lat_deg=float(lat[0]), lon_deg=float(lon[0]), alt_amsl_m=0.0)
    half_m = 0.5 * min(w, h) * a.georef.gsd_m
    rows: list[tuple[str, dict[str, float]]] = []
    for height in heights:
        # The frame's half-width at 5 degrees of tilt, the prior's offset and the search.
        reach = height * (np.tan(np.radians(28.5 + TILT_DEG)) + 0.1) + 80.0
        spread = half_m - reach
        if spread <= 0.0:
            print(f"real: {height:.0f} m frames do not fit in {a_path} ({2 * half_m:.0f} m)")
            continue
        for name, frames in (("A-B", b), ("A-A", a)):
            rng = np.random.default_rng([seed, 12, int(height)])
            acc, resp = matcher_figure(a, frames, home, height, count, rng, spread)
            rows.append(
                (f"real {name} @{height:.0f} m", {"accept": acc, "response": resp, "n": count})
            )
    return rows


def real_pairs(a_dir: Path, b_dir: Path) -> Iterator[tuple[str, Bgr, Bgr]]:
    """(name, A, B) for each file name present in both folders (3-channel, same size)."""
    for pa in sorted(a_dir.iterdir()):
        pb = b_dir / pa.name
        if not pb.is_file():
            continue
        a, b = cv2.imread(str(pa), cv2.IMREAD_COLOR), cv2.imread(str(pb), cv2.IMREAD_COLOR)
        if a is None or b is None or a.shape != b.shape or min(a.shape[:2]) < CROP:
            continue
        yield pa.name, np.asarray(a, dtype=np.uint8), np.asarray(b, dtype=np.uint8)


def real_rows(
    a_dir: Path, b_dir: Path, crops: int, seed: int, keep: list[list[Bgr]] | None
) -> list[tuple[str, dict[str, float]]]:
    """Rows ``real A-B`` and ``real A-A (same)``: crops spread evenly over the pairs."""
    pairs = list(real_pairs(a_dir, b_dir))
    if not pairs:
        sys.exit(f"--real {a_dir} {b_dir}: no pairs of same-size images of >= {CROP} px")
    rng = np.random.default_rng([seed, 3])
    diff, same = Figures("real A-B"), Figures("real A-A")
    reg_d, reg_s = np.random.default_rng([seed, 8]), np.random.default_rng([seed, 9])
    per_pair = max(1, -(-crops // len(pairs)))
    for _name, a, b in pairs:
        h, w = a.shape[:2]
        for _ in range(per_pair):
            y = int(rng.integers(0, h - CROP + 1))
            x = int(rng.integers(0, w - CROP + 1))
            ca, cb = a[y : y + CROP, x : x + CROP], b[y : y + CROP, x : x + CROP]
            diff.add(ca, cb, reg_d)
            same.add(ca, ca, reg_s)
        if keep is not None and len(keep) < 4:
            keep.append([a[:CROP, :CROP], b[:CROP, :CROP]])
    return [("real A-B", diff.row()), ("real A-A (same)", same.row())]


def _fmt(value: float, key: str) -> str:
    return f"{100 * value:5.0f} %" if key == "reg" else f"{value:7.2f}"


def print_table(rows: list[tuple[str, dict[str, float]]], out: Callable[[str], None]) -> None:
    """The figures beside the targets."""
    out(
        f"{'pairs':<22}{'n':>4}{'NCC med':>9}{'reg':>8}{'reg8':>8}{'peak':>7}{'oc1':>7}"
        f"{'oc2':>7}{'flip':>7}{'sat':>8}{'slope':>8}{'tex1':>6}{'tex2':>6}"
    )
    for name, r in rows:
        out(
            f"{name:<22}{int(r['n']):>4}{_fmt(r['ncc'], 'ncc'):>9}{_fmt(r['reg'], 'reg'):>8}"
            f"{_fmt(r['reg8'], 'reg'):>8}{r['peak']:>7.2f}{r['oc1']:>7.2f}{r['oc2']:>7.2f}"
            f"{100 * r['flip']:>5.0f} %{_fmt(r['sat'], 'sat'):>8}{_fmt(r['slope'], 'slope'):>8}"
            f"{r['tex1']:>6.2f}{r['tex2']:>6.2f}"
        )
    t = TARGETS
    out(
        f"targets (date 0-2): NCC {t['ncc'][0]}-{t['ncc'][1]}, reg {t['reg'][0]:.0%}-"
        f"{t['reg'][1]:.0%}, same date 100 %, sat {t['sat'][0]:.0f}-{t['sat'][1]:.0f}, "
        f"slope {t['slope'][0]}..{t['slope'][1]}; reg8 {t['reg8'][0]:.0%}-{t['reg8'][1]:.0%}, "
        f"peak {t['peak'][0]}-{t['peak'][1]}"
    )


def print_matcher_table(
    rows: list[tuple[str, dict[str, float]]], out: Callable[[str], None]
) -> None:
    """The matcher figure: share of frames accepted within 5 m and the median response."""
    out(f"{'frames matched against date 0':<30}{'n':>4}{'accepted < 5 m':>16}{'response':>10}")
    for name, r in rows:
        out(f"{name:<30}{int(r['n']):>4}{100 * r['accept']:>14.0f} %{r['response']:>10.2f}")
    t = TARGETS
    out(
        f"targets (date 0-2): accepted {t['accept_low'][0]:.0%}-{t['accept_low'][1]:.0%} at "
        f"200-300 m, at most {t['accept_high'][1]:.0%} at 3000 m; 0-1 above 0-2; same date "
        f">= {t['accept_same'][0]:.0%}"
    )


def contact_sheet(procedural: list[list[Bgr]], real: list[list[Bgr]], path: Path) -> None:
    """Rows of crops: each procedural place at dates 0, 1, 2; each real pair A, B."""
    gap = 6
    rows = procedural + real
    width = 3 * CROP + 2 * gap
    sheet = np.full((len(rows) * (CROP + gap), width, 3), 255, np.uint8)
    for i, imgs in enumerate(rows):
        for j, img in enumerate(imgs):
            y, x = i * (CROP + gap), j * (CROP + gap)
            sheet[y : y + CROP, x : x + CROP] = img
    cv2.imwrite(str(path), sheet)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--crops", type=int, default=48, help="random crops per map (default 48)")
    p.add_argument("--seed", type=int, default=0, help="seed of the crop places (default 0)")
    p.add_argument("--map-seed", type=int, default=0, help="seed of the maps (default 0)")
    p.add_argument("--maps", default=",".join(KINDS), help="procedural maps (default: all)")
    p.add_argument("--real", nargs=2, metavar=("A_DIR", "B_DIR"), type=Path)
    tifs_help = "matcher figure on two real GeoTIFFs of one place (A the reference)"
    p.add_argument("--real-tifs", nargs=2, metavar=("A_TIF", "B_TIF"), type=Path, help=tifs_help)
    frames_help = "matcher frames per world, date and height (default 20; 0: none)"
    p.add_argument("--frames", type=int, default=20, help=frames_help)
    p.add_argument("--sheet", type=Path, help="save crops side by side as this PNG")
    p.add_argument(
        "--heights", default="200,300,3000", help="matcher heights m (default 200,300,3000)"
    )
    args = p.parse_args(argv)
    heights = tuple(float(h) for h in args.heights.split(",") if h)
    for kind in [k for k in args.maps.split(",") if k]:
        if kind not in KINDS:
            p.error(f"--maps: {kind!r} is not a procedural map ({', '.join(KINDS)})")
    keep_p: list[list[Bgr]] | None = [] if args.sheet else None
    keep_r: list[list[Bgr]] | None = [] if args.sheet else None
    rows: list[tuple[str, dict[str, float]]] = []
    for kind in [k for k in args.maps.split(",") if k]:
        rows += procedural_rows(kind, args.crops, args.seed, args.map_seed, keep_p, True)
    if args.real:
        rows += real_rows(args.real[0], args.real[1], args.crops, args.seed, keep_r)
    for kind in [k for k in args.maps.split(",") if k]:
        print(f"{kind} dates: " + ", ".join(f"{d.index} = {d.full_label}" for d in dates_of(kind)))
    print_table(rows, print)
    if args.frames > 0:
        mrows: list[tuple[str, dict[str, float]]] = []
        for kind in [k for k in args.maps.split(",") if k]:
            mrows += matcher_rows(kind, args.frames, args.seed, args.map_seed, heights)
        if args.real_tifs:
            a_tif, b_tif = args.real_tifs
            mrows += real_tif_rows(a_tif, b_tif, args.frames, args.seed, heights)
        print_matcher_table(mrows, print)
    if args.sheet:
        contact_sheet(keep_p or [], keep_r or [], args.sheet)
        print(f"sheet: {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
