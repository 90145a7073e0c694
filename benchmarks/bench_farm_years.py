"""Farmland's year gaps against a real NAIP series of one place, at 5 m (issue 32).

    python benchmarks/bench_farm_years.py --naip DIR [--map-seed 0] [--pairs 2009:2012,...]
        [--sheet OUT.png]

``DIR`` holds NAIP GeoTIFFs of one quarter quad, one per year (4 bands R, G, B, NIR; the file
name ends in ``_YYYYMMDD.tif``), resampled to 5 m. For each pair of years (the earlier A, the
later B) and for the ``farmland`` map's dates rendered at 5 m over a window of the same size
(date 0 -> 1 is 3 years, 0 -> 2 is 7), the simple physical statistics a model of farmland's
years must reproduce, the same code on both:

- ``fields``: the parcels both years share (regions bounded by the two years' strong edges
  and water, at least 1 ha), their count;
- ``tone r``: correlation of the fields' mean grey in A and B; ``rot``: share of field area
  whose tone class (dark, middle, bright third of the fields by area) changes;
- ``flip``: share of neighbouring field pairs (more than 6 grey levels apart in A) whose
  brightness order is the other way round in B;
- ``wat A``, ``wat B``: open water, share of the area (NIR below half its median; the
  map's water code for ``farmland``); ``wat kept``: share of A's water that is water in B;
- ``in10``, ``in50``: persistence inside fields: correlation of A's and B's residuals after
  removing each field's mean, averaged to 10 m and to 50 m (pixels 10 m inside the field);
- ``edge``: share of A's strongest 10 % gradients (10 m) that are among B's strongest 10 %
  within 10 m; ``oc1``: single-angle orientation agreement of the 10 m gradients;
- ``ncc``, ``reg8``, ``peak``: bench_dates' crop figures on 256 x 256 crops at 5 m.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_dates import HOME, Figures

from air_sitl.maps.procedural import ProceduralMap
from air_sitl.maps.procedural.canvas import dates_of
from air_sitl.maps.procedural.farmland import FarmlandWorld
from air_sitl.maps.procedural.farmland_built import WATER

GSD_M = 5.0
PAIRS = "2009:2010,2009:2012,2010:2014,2012:2016,2016:2019,2009:2016,2012:2019,2009:2019,2010:2020"
MIN_FIELD_PX = 400  # 1 ha
FLIP_DN = 6.0
NEIGHBOUR_PX = 9  # fields facing each other across 40 m of edge, road or ditch
Img = npt.NDArray[np.uint8]
Mask = npt.NDArray[np.bool_]
Floats = npt.NDArray[np.float32]
Survey = tuple[Img, Mask]  # BGR and its open water


def naip_series(folder: Path) -> dict[str, Survey]:
    """{date: (BGR, open water)} of every ``*_YYYYMMDD.tif`` in ``folder``, cut to a common size."""
    import rasterio  # GDAL: only for real GeoTIFFs

    out: dict[str, Survey] = {}
    for path in sorted(folder.glob("*.tif")):
        stamp = path.stem.rsplit("_", 1)[-1]
        date = f"{stamp[:4]}-{stamp[4:6]}-{stamp[6:8]}"
        with rasterio.open(path) as src:
            a = src.read()
        if a.shape[0] < 4:
            sys.exit(f"--naip: {path}: {a.shape[0]} bands, 4 wanted (R, G, B, NIR)")
        nir = a[3].astype(np.float32)
        out[date] = (np.dstack([a[2], a[1], a[0]]), nir < 0.5 * float(np.median(nir)))
    if not out:
        sys.exit(f"--naip: {folder}: no GeoTIFFs")
    h = min(v[0].shape[0] for v in out.values())
    w = min(v[0].shape[1] for v in out.values())
    return {k: (np.ascontiguousarray(b[:h, :w]), m[:h, :w]) for k, (b, m) in out.items()}


def farmland_series(map_seed: int, shape: tuple[int, int]) -> dict[str, Survey]:
    """{date: (BGR, open water)} of the farmland map's three dates at 5 m around home."""
    h, w = shape
    size = max(h, w)
    out: dict[str, Survey] = {}
    for d in dates_of("farmland"):
        m = ProceduralMap("farmland", HOME, seed=map_seed, date=d.index, gsd_m=GSD_M)
        ox, oy = m.origin_abs_px
        x0 = ox + int(m.home_px[0]) - size // 2
        y0 = oy + int(m.home_px[1]) - size // 2
        bgr = m.render_abs(x0, y0, size)[:h, :w]
        code = FarmlandWorld(map_seed).land_cover(x0, y0, size, GSD_M, m.date)[:h, :w]
        out[d.label] = (np.ascontiguousarray(bgr), code == WATER)
    return out


def grey(bgr: Img) -> Floats:
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(np.float32)


def gradients(g: Floats) -> tuple[Floats, Floats]:
    s = cv2.GaussianBlur(g, (0, 0), 1.0)
    gx = np.asarray(cv2.Sobel(s, cv2.CV_32F, 1, 0, ksize=3), np.float32)
    return gx, np.asarray(cv2.Sobel(s, cv2.CV_32F, 0, 1, ksize=3), np.float32)


def shared_fields(ga: Floats, gb: Floats, water: Mask) -> tuple[npt.NDArray[np.int32], int]:
    """Labels of the regions both years agree are parcels: bounded by either year's strong
    edges (above 2.5 times its median gradient) and by water; regions of at least 1 ha."""
    edges = water.copy()
    for g in (ga, gb):
        gx, gy = gradients(g)
        mag = np.hypot(gx, gy)
        edges |= mag > 2.5 * float(np.median(mag))
    edges = cv2.dilate(edges.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
    n, lab = cv2.connectedComponents((~edges).astype(np.uint8), connectivity=4)
    counts = np.bincount(lab.ravel(), minlength=n)
    keep = counts >= MIN_FIELD_PX
    keep[0] = False
    remap = np.zeros(n, np.int32)
    remap[keep] = np.arange(1, int(keep.sum()) + 1)
    lab = remap[lab]
    lab[edges] = 0
    return lab, int(keep.sum())


def field_means(g: Floats, lab: npt.NDArray[np.int32], n: int) -> npt.NDArray[np.float64]:
    """Mean grey of each label 0..n (0: edges and water)."""
    area = np.maximum(np.bincount(lab.ravel(), minlength=n + 1), 1)
    means: npt.NDArray[np.float64] = np.bincount(lab.ravel(), g.ravel(), n + 1) / area
    return means


def corr(a: Floats, b: Floats) -> float:
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt((a * a).sum() * (b * b).sum()))
    return float((a * b).sum() / den) if den > 0 else float("nan")


def residual_corr(ga: Floats, gb: Floats, lab: npt.NDArray[np.int32], n: int, cell: int) -> float:
    """Correlation of A's and B's residuals (each field's mean removed), averaged over cells of
    ``cell`` px, over cells lying wholly 10 m inside one field."""
    inner = cv2.erode((lab > 0).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    vals = []
    for g in (ga, gb):
        vals.append(np.where(inner, g - field_means(g, lab, n)[lab], 0.0).astype(np.float32))
    h, w = (ga.shape[0] // cell) * cell, (ga.shape[1] // cell) * cell

    def pool(x: Floats) -> Floats:
        return np.asarray(
            x[:h, :w].reshape(h // cell, cell, w // cell, cell).mean(axis=(1, 3)), np.float32
        )

    full = pool(inner.astype(np.float32)) > 0.999
    ra, rb = pool(vals[0])[full], pool(vals[1])[full]
    return corr(ra, rb) if ra.size > 10 else float("nan")


def resid_sd(g: Floats, lab: npt.NDArray[np.int32], n: int) -> float:
    """Standard deviation (grey levels) of the 10 m residuals inside the fields."""
    inner = cv2.erode((lab > 0).astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    r = cv2.blur(np.where(inner, g - field_means(g, lab, n)[lab], 0.0).astype(np.float32), (2, 2))
    return float(r[inner].std())


def pair_stats(a: Survey, b: Survey, rng: np.random.Generator) -> dict[str, float]:
    """The statistics of one pair of surveys (A the earlier)."""
    ga, gb = grey(a[0]), grey(b[0])
    water = a[1] | b[1]
    lab, n = shared_fields(ga, gb, water)
    area = np.bincount(lab.ravel(), minlength=n + 1)[1:].astype(np.float64)
    ma, mb = field_means(ga, lab, n)[1:], field_means(gb, lab, n)[1:]

    def tercile(m: npt.NDArray[np.float64]) -> npt.NDArray[np.int64]:
        order = np.argsort(m)
        cum = np.cumsum(area[order]) / area.sum()
        cls = np.empty(n, np.int64)
        cls[order] = np.minimum((cum * 3.0).astype(np.int64), 2)
        return cls

    rot = float(area[tercile(ma) != tercile(mb)].sum() / area.sum())
    # Neighbours: labels meeting across a dilation of 3 px (their shared edge).
    ring = np.ones((NEIGHBOUR_PX, NEIGHBOUR_PX), np.uint8)
    big = cv2.dilate(lab.astype(np.float32), ring).astype(np.int32)
    none = np.float32(n + 1)
    small = cv2.erode(np.where(lab > 0, lab, none).astype(np.float32), ring)
    small = small.astype(np.int32)
    sel = (big > 0) & (small <= n) & (big != small)
    pairs = {(int(p), int(q)) for p, q in zip(small[sel], big[sel], strict=True)}
    diffs = [(ma[p - 1] - ma[q - 1], mb[p - 1] - mb[q - 1]) for p, q in pairs]
    strong = [(da, db) for da, db in diffs if abs(da) > FLIP_DN]
    flip = sum(da * db < 0 for da, db in strong) / max(len(strong), 1)
    # Edges and gradients at 10 m.
    sa, sb = (
        np.asarray(cv2.resize(g, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA), np.float32)
        for g in (ga, gb)
    )
    (ax, ay), (bx, by) = gradients(sa), gradients(sb)
    mag_a, mag_b = np.hypot(ax, ay), np.hypot(bx, by)
    top_a = mag_a > np.percentile(mag_a, 90)
    top_b = (mag_b > np.percentile(mag_b, 90)).astype(np.uint8)
    top_b = cv2.dilate(top_b, np.ones((3, 3), np.uint8)) > 0
    oc1 = float((ax * bx + ay * by).sum() / max(float((mag_a * mag_b).sum()), 1e-6))
    crops = Figures("")
    h, w = ga.shape
    for _ in range(6):
        y, x = int(rng.integers(0, h - 256 + 1)), int(rng.integers(0, w - 256 + 1))
        crops.add(a[0][y : y + 256, x : x + 256], b[0][y : y + 256, x : x + 256], rng, GSD_M)
    row = crops.row()
    out = {"fields": float(n), "pairs": float(len(strong)), "flip": float(flip), "rot": rot}
    out["tone_r"] = corr(ma.astype(np.float32), mb.astype(np.float32))
    out["f_sd"] = float(np.sqrt(np.cov(mb, aweights=area)))
    out["in_sd"] = resid_sd(gb, lab, n)
    out["wat_a"], out["wat_b"] = float(a[1].mean()), float(b[1].mean())
    out["wat_kept"] = float((a[1] & b[1]).sum() / max(int(a[1].sum()), 1))
    out["in10"] = residual_corr(ga, gb, lab, n, 2)
    out["in50"] = residual_corr(ga, gb, lab, n, 10)
    out["edge"] = float((top_a & top_b).sum() / max(int(top_a.sum()), 1))
    out["oc1"] = oc1
    return out | {k: row[k] for k in ("ncc", "reg8", "peak")}


COLUMNS = ("fields", "tone_r", "rot", "flip", "pairs", "f_sd", "in_sd", "wat_a", "wat_b",
           "wat_kept", "in10", "in50", "edge", "oc1", "ncc", "reg8", "peak")  # fmt: skip


def print_rows(rows: list[tuple[str, dict[str, float]]]) -> None:
    print(f"{'pair':<28}" + "".join(f"{c:>9}" for c in COLUMNS))
    for name, r in rows:
        cells = []
        for c in COLUMNS:
            v = r[c]
            pct = c in ("rot", "flip", "wat_a", "wat_b", "wat_kept", "edge", "reg8")
            whole = c in ("fields", "pairs")
            cells.append(f"{100 * v:>7.0f} %" if pct else f"{v:>9.0f}" if whole else f"{v:>9.2f}")
        print(f"{name:<28}" + "".join(cells))


def save_sheet(rows: list[list[tuple[str, Img]]], path: Path) -> None:
    """Rows of labelled images side by side, at half size (10 m a pixel)."""
    out = []
    for row in rows:
        cells = []
        for label, img in row:
            small = cv2.resize(
                img, (img.shape[1] // 2, img.shape[0] // 2), interpolation=cv2.INTER_AREA
            )
            cv2.putText(small, label, (8, 22), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 2)
            cells.append(small)
        out.append(np.hstack(cells))
    cv2.imwrite(str(path), np.vstack(out), [cv2.IMWRITE_JPEG_QUALITY, 85])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--naip", type=Path, help="folder of one place's NAIP GeoTIFFs (4 bands, 5 m)")
    p.add_argument("--pairs", default=PAIRS, help="real year pairs A:B (default: 9 of 1-11 years)")
    p.add_argument("--map-seed", type=int, default=0, help="seed of the farmland map (default 0)")
    p.add_argument("--seed", type=int, default=0, help="seed of the crops (default 0)")
    p.add_argument("--sheet", type=Path, help="save our three dates beside NAIP's (.jpg, .png)")
    args = p.parse_args(argv)
    rows: list[tuple[str, dict[str, float]]] = []
    shape = (723, 934)
    real: dict[str, Survey] = {}
    if args.naip:
        real = naip_series(args.naip)
        shape = next(iter(real.values()))[0].shape[:2]
        by_year = {k[:4]: k for k in real}
        for pair in [q for q in args.pairs.split(",") if q]:
            ya, yb = pair.split(":")
            if ya not in by_year or yb not in by_year:
                missing = ya if ya not in by_year else yb
                sys.exit(f"--pairs: {pair}: no NAIP survey of {missing} in {args.naip}")
            ka, kb = by_year[ya], by_year[yb]
            rng = np.random.default_rng([args.seed, int(ya), int(yb)])
            rows.append((f"NAIP {ka} -> {kb[:4]}", pair_stats(real[ka], real[kb], rng)))
    ours = farmland_series(args.map_seed, shape)
    labels = list(ours)
    for d in (0, 1, 2):
        rng = np.random.default_rng([args.seed, 5, d])
        stats = pair_stats(ours[labels[0]], ours[labels[d]], rng)
        rows.append((f"farmland 0-{d} ({labels[d][:4]})", stats))
    print_rows(rows)
    if args.sheet:
        picks = [k for k in real if k[:4] in ("2009", "2012", "2016")]
        rows_of = [[(f"farmland {k}", ours[k][0]) for k in labels]]
        if len(picks) == 3:
            rows_of.append([(f"NAIP {k}", real[k][0]) for k in picks])
        save_sheet(rows_of, args.sheet)
        print(f"sheet: {args.sheet}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
