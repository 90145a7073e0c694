"""How different the dates of a procedural map are, against real imagery of different years.

    python benchmarks/bench_dates.py [--crops 48] [--seed 0] [--maps urban,forest]
        [--real A_DIR B_DIR] [--sheet OUT.png]

For each procedural map, random 256 x 256 crops at 0.5 m per pixel of date 0 against the same
place at date 1 and date 2 (and date 0 against itself: the same-date check), in grey:

- ``ncc``: zero-mean normalised cross-correlation of the two crops (median over crops);
- ``reg``: template registration success: the central 128 x 128 of B moved by a known random
  offset of up to 40 px is found in A with OpenCV ``matchTemplate`` (TM_CCOEFF_NORMED);
  success = the peak within 3 px of the truth;
- ``sat``: mean HSV saturation (OpenCV's 0..255) of the B crops;
- ``slope``: radially averaged power-spectrum slope of the B crops (grey, Hann window, 4-100
  cycles per 256 px, least squares in log-log), the median over crops.

``--real A_DIR B_DIR``: the same figures for pairs of images with the same file names in two
folders (public change-detection samples: A the earlier year, B the later); images larger than
256 px give several crops. Targets (issue 24) are printed beside. ``--sheet`` saves crops of
dates 0/1/2 of each map side by side with real pairs, to look at. Deterministic with ``--seed``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.maps.procedural import ProceduralMap
from air_sitl.state import GeoPoint

CROP = 256
TEMPLATE = 128
MAX_OFFSET = 40
HIT_PX = 3.0
GSD_M = 0.5
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
SPREAD_PX = 12_000  # crops are taken within 6 km of home
# Issue 24's targets (date 0 vs 2, urban and forest) and what real pairs measured.
TARGETS = {
    "ncc": (0.15, 0.50),
    "reg": (0.15, 0.70),
    "same": (1.0, 1.0),
    "sat": (30.0, 70.0),
    "slope": (-2.40, -1.95),
}

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


def registers(a: Gray, b: Gray, rng: np.random.Generator) -> bool:
    """Whether B's central template moved by a random offset is found in A within 3 px."""
    dx, dy = (int(v) for v in rng.integers(-MAX_OFFSET, MAX_OFFSET + 1, size=2))
    c = (CROP - TEMPLATE) // 2
    tpl = b[c + dy : c + dy + TEMPLATE, c + dx : c + dx + TEMPLATE]
    res = cv2.matchTemplate(a, tpl, cv2.TM_CCOEFF_NORMED)
    _, _, _, (mx, my) = cv2.minMaxLoc(res)
    return bool(np.hypot(mx - (c + dx), my - (c + dy)) <= HIT_PX)


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
        self.sats: list[float] = []
        self.slopes: list[float] = []

    def add(self, a: Bgr, b: Bgr, rng: np.random.Generator) -> None:
        ga, gb = gray(a), gray(b)
        self.nccs.append(ncc(ga, gb))
        self.hits.append(registers(ga, gb, rng))
        self.sats.append(saturation(b))
        self.slopes.append(spectrum_slope(gb))

    def row(self) -> dict[str, float]:
        return {
            "ncc": float(np.median(self.nccs)),
            "reg": float(np.mean(self.hits)),
            "sat": float(np.mean(self.sats)),
            "slope": float(np.median(self.slopes)),
            "n": float(len(self.nccs)),
        }


def procedural_rows(
    kind: str, crops: int, seed: int, map_seed: int, keep: list[list[Bgr]] | None
) -> list[tuple[str, dict[str, float]]]:
    """Rows ``kind 0-0``, ``kind 0-1``, ``kind 0-2`` over the same random places."""
    maps = [ProceduralMap(kind, HOME, seed=map_seed, date=d, gsd_m=GSD_M) for d in (0, 1, 2)]
    ox, oy = maps[0].origin_abs_px
    rng = np.random.default_rng([seed, 1 if kind == "urban" else 2])
    places = rng.integers(-SPREAD_PX // 2, SPREAD_PX // 2, size=(crops, 2))
    figs = {d: Figures(f"{kind} 0-{d}") for d in (0, 1, 2)}
    reg_rngs = {d: np.random.default_rng([seed, 7, d]) for d in (0, 1, 2)}
    for i, (px, py) in enumerate(places):
        x0, y0 = ox + 5120 + int(px), oy + 5120 + int(py)
        imgs = [m.render_abs(x0, y0, CROP) for m in maps]
        for d in (0, 1, 2):
            figs[d].add(imgs[0], imgs[d], reg_rngs[d])
        if keep is not None and i < 2:
            keep.append(imgs)
    return [(f"{kind} 0-{d}" + (" (same)" if d == 0 else ""), figs[d].row()) for d in (0, 1, 2)]


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
    out(f"{'pairs':<22}{'n':>4}{'NCC med':>9}{'reg':>8}{'sat':>8}{'slope':>8}")
    for name, r in rows:
        out(
            f"{name:<22}{int(r['n']):>4}{_fmt(r['ncc'], 'ncc'):>9}{_fmt(r['reg'], 'reg'):>8}"
            f"{_fmt(r['sat'], 'sat'):>8}{_fmt(r['slope'], 'slope'):>8}"
        )
    t = TARGETS
    out(
        f"targets (date 0-2): NCC {t['ncc'][0]}-{t['ncc'][1]}, reg {t['reg'][0]:.0%}-"
        f"{t['reg'][1]:.0%}, same date 100 %, sat {t['sat'][0]:.0f}-{t['sat'][1]:.0f}, "
        f"slope {t['slope'][0]}..{t['slope'][1]}"
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
    p.add_argument("--maps", default="urban,forest", help="procedural maps (default both)")
    p.add_argument("--real", nargs=2, metavar=("A_DIR", "B_DIR"), type=Path)
    p.add_argument("--sheet", type=Path, help="save crops side by side as this PNG")
    args = p.parse_args(argv)
    keep_p: list[list[Bgr]] | None = [] if args.sheet else None
    keep_r: list[list[Bgr]] | None = [] if args.sheet else None
    rows: list[tuple[str, dict[str, float]]] = []
    for kind in [k for k in args.maps.split(",") if k]:
        rows += procedural_rows(kind, args.crops, args.seed, args.map_seed, keep_p)
    if args.real:
        rows += real_rows(args.real[0], args.real[1], args.crops, args.seed, keep_r)
    print_table(rows, print)
    if args.sheet:
        contact_sheet(keep_p or [], keep_r or [], args.sheet)
        print(f"sheet: {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
