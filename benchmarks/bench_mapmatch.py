"""Map matching: which correlator, and how well ``mapmatch`` / ``fused`` do, on real archives.

    python benchmarks/bench_mapmatch.py ARCHIVE [ARCHIVE ...] [--correlators] [--methods]
        [--step 100] [--limit N]
    python benchmarks/bench_mapmatch.py --frames [--maps urban,forest] [--dates 0,1,2]
        [--heights 200,300] [--count 40] [--inversions none,global,checker] [--calibrate]

``--correlators``: every ``--step``-th frame of each archive, rectified with the recorded AHRS
attitude and the true height plus 0.5 m noise around a prior 0-10 m off the truth (and, to see
wrong matches, 400 m off), against the reference date (0, or 1 for a date-0 flight). For each
correlator on the same patches: share of right fixes (< 5 m), median error, the peak ratio
(second / first peak) of right matches (p95) beside that of wrong ones (p5, 400 m off): the
gap between them is what a quality gate can use. Orientation correlation is the method's.

``--methods``: ``mapmatch``, ``mapmatch-axial`` and ``fused`` through the offline driver (writing
``estimates/<method>.csv`` into the archive: pass copies), scored against ``frames.csv``:
median, p95, max horizontal error, recall at 25 m over all capture frames, availability,
share of frames > 50 m off, share of frames with an accepted fix, and speed as frames per
second of this process's CPU time on one OpenCV thread (the one-core figure, whatever else
the machine runs) and of wall time.

``--frames`` (no archive): frames rendered from each map (``--maps``) at each date
(``--dates``, against date 0) and height (``--heights``), ``--count`` random places and headings
with roll and pitch up to 5 degrees, each matched by every registered map-matching method's
matcher (``mapmatch``, ``mapmatch-axial``: correlator and gate) from a prior 10-30 m off, and
400 m off (a wrong place); also with the frame's contrast reversed (``--inversions``: ``global``
255 - image, ``checker`` every other cell of a 4 x 4 grid). Per line: share accepted within
5 m, accepted farther, median response, wrong places accepted, CPU ms per frame (both
matches) of each method in the same run. ``--calibrate``: each method's gate thresholds
matched to ``mapmatch``'s on the same-date control (``--dates 0``): how ``mapmatch-axial``'s
were set.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from air_sitl.camera.model import CameraModel
from air_sitl.dataset.reader import open_archive
from air_sitl.localize.archive import context_of, observations, run_method
from air_sitl.localize.base import Localizer
from air_sitl.localize.mapmatch import open_reference
from air_sitl.localize.mapmatch_core import (
    MapMatcher,
    Rectified,
    Scored,
    orientation_correlation,
)
from air_sitl.state import GeoPoint

WRONG_OFFSET_M = 400.0
RIGHT_M = 5.0


# -- correlators on the same rectified patches ------------------------------------------------
def ncc_grey(rect: Rectified) -> Scored:
    score = cv2.matchTemplate(
        rect.reference, rect.patch, cv2.TM_CCOEFF_NORMED, mask=rect.patch_mask
    )
    return np.nan_to_num(score).astype(np.float32), 1.0


def _grad(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    f = img.astype(np.float32)
    return cv2.Sobel(f, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(f, cv2.CV_32F, 0, 1, ksize=3)


def ncc_gradient(rect: Rectified) -> Scored:
    a = cv2.magnitude(*_grad(rect.patch))
    b = cv2.magnitude(*_grad(rect.reference))
    mask = cv2.erode(rect.patch_mask, np.ones((3, 3), np.uint8))
    score = cv2.matchTemplate(b, a, cv2.TM_CCOEFF_NORMED, mask=mask)
    return np.nan_to_num(score).astype(np.float32), 1.0


def gradient_correlation(rect: Rectified) -> Scored:
    """Complex gradients (gx + i gy), not normalised: strong edges dominate."""
    ax, ay = _grad(rect.patch)
    keep = rect.patch_mask == 0
    ax[keep] = 0.0
    ay[keep] = 0.0
    bx, by = _grad(rect.reference)
    a = ax + 1j * ay
    b = bx + 1j * by
    h, w = b.shape
    corr = np.fft.ifft2(np.fft.fft2(b) * np.conj(np.fft.fft2(a, (h, w)))).real
    m = 2 * rect.margin_px + 1
    norm = math.sqrt(
        float(np.sum(np.abs(a) ** 2)) * float(np.sum(np.abs(b) ** 2)) * a.size / b.size
    )
    return corr[:m, :m].astype(np.float32), norm


def orb_ransac(rect: Rectified) -> tuple[float, float, int] | None:
    """ORB + RANSAC similarity: (shift x, shift y in level px, inliers), None without one."""
    orb = cv2.ORB_create(nfeatures=600, fastThreshold=10)
    ka, da = orb.detectAndCompute(rect.patch, rect.patch_mask)
    kb, db = orb.detectAndCompute(rect.reference, rect.reference_mask)
    if da is None or db is None or len(ka) < 8 or len(kb) < 8:
        return None
    pairs = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(da, db, k=2)
    good = [p[0] for p in pairs if len(p) == 2 and p[0].distance < 0.8 * p[1].distance]
    if len(good) < 6:
        return None
    src = np.float32([ka[g.queryIdx].pt for g in good])
    dst = np.float32([kb[g.trainIdx].pt for g in good])
    m, inl = cv2.estimateAffinePartial2D(src, dst, method=cv2.RANSAC, ransacReprojThreshold=3.0)
    if m is None:
        return None
    ph, pw = rect.patch.shape
    c = np.array([(pw - 1) / 2.0, (ph - 1) / 2.0, 1.0])
    moved = m @ c
    return (
        float(moved[0] - c[0] - rect.margin_px),
        float(moved[1] - c[1] - rect.margin_px),
        int(inl.sum()),
    )


def _truth(archive: Path) -> list[dict[str, str]]:
    with (archive / "frames.csv").open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def correlators(archives: list[Path], step: int) -> None:
    """Print the comparison table of the correlators (see the module docstring)."""
    scorers = {
        "ncc-grey": ncc_grey,
        "ncc-gradient": ncc_gradient,
        "gradient-corr": gradient_correlation,
        "orientation": orientation_correlation,
    }
    rows_out: dict[str, dict[str, list[float]]] = {
        k: {"err": [], "ratio": [], "wrong_ratio": [], "cpu": []} for k in [*scorers, "orb-ransac"]
    }
    orb_inliers: dict[str, list[float]] = {"right": [], "wrong": []}
    rng = np.random.default_rng(1)
    for archive in archives:
        with open_archive(archive) as arch:
            context = context_of(arch)
        home = context.home
        matcher = MapMatcher(open_reference(context), CameraModel(), home, min_response=-1.0)
        imu = np.loadtxt(archive / "imu.csv", delimiter=",", skiprows=1)
        for r in _truth(archive)[::step]:
            t = int(r["sim_time_ns"])
            i = int(np.searchsorted(imu[:, 0], t, side="right")) - 1
            q = (float(imu[i, 7]), float(imu[i, 8]), float(imu[i, 9]), float(imu[i, 10]))
            east, north = float(r["east_m"]), float(r["north_m"])
            h = float(r["alt_rel_m"]) + float(rng.normal(0.0, 0.5))
            jpeg = (archive / r["filename"]).read_bytes()
            pe, pn = east + float(rng.uniform(-10, 10)), north + float(rng.uniform(-10, 10))
            for wrong in (False, True):
                off = WRONG_OFFSET_M if wrong else 0.0
                rect = matcher.rectify(jpeg, q, h, pe + off, pn, 20.0)
                if rect is None:
                    continue
                for name, fn in scorers.items():
                    c0 = time.process_time()
                    res = matcher.locate(rect, fn(rect))
                    rows_out[name]["cpu"].append(time.process_time() - c0)
                    if res is None:
                        continue
                    if wrong:
                        rows_out[name]["wrong_ratio"].append(res.peak_ratio)
                    else:
                        rows_out[name]["err"].append(
                            math.hypot(res.east_m - east, res.north_m - north)
                        )
                        rows_out[name]["ratio"].append(res.peak_ratio)
                c0 = time.process_time()
                orb = orb_ransac(rect)
                rows_out["orb-ransac"]["cpu"].append(time.process_time() - c0)
                if orb is None:
                    continue
                orb_inliers["wrong" if wrong else "right"].append(orb[2])
                if not wrong:
                    s = 1 << rect.level
                    dn, de = matcher._jac_inv @ np.array([orb[0] * s, orb[1] * s])
                    rows_out["orb-ransac"]["err"].append(
                        math.hypot(pe + de - east, pn + dn - north)
                    )
    n_frames = sum(len(_truth(a)[::step]) for a in archives)
    print(f"correlators: {n_frames} frames of {', '.join(a.name for a in archives)}")
    print(f"{'correlator':14s} {'right<5m':>8s} {'median m':>8s} {'ratio p95':>9s} "
          f"{'wrong p5':>8s} {'gap':>6s} {'ms/match':>8s}")  # fmt: skip
    for name, d in rows_out.items():
        err = np.array(d["err"])
        right = float(np.mean(err < RIGHT_M)) * len(err) / n_frames if len(err) else 0.0
        ms = 1e3 * float(np.mean(d["cpu"])) if d["cpu"] else math.nan
        if name == "orb-ransac":
            ri = orb_inliers["right"]
            wi = orb_inliers["wrong"]
            print(f"{name:14s} {right:8.3f} {np.median(err) if len(err) else math.nan:8.2f} "
                  f"inliers right p5 {np.percentile(ri, 5) if ri else math.nan:.0f}, wrong p95 "
                  f"{np.percentile(wi, 95) if wi else math.nan:.0f} {ms:8.2f}")  # fmt: skip
            continue
        rp95 = float(np.percentile(d["ratio"], 95)) if d["ratio"] else math.nan
        wp5 = float(np.percentile(d["wrong_ratio"], 5)) if d["wrong_ratio"] else math.nan
        print(f"{name:14s} {right:8.3f} {np.median(err):8.2f} {rp95:9.2f} {wp5:8.2f} "
              f"{wp5 - rp95:6.2f} {ms:8.2f}")  # fmt: skip
    print("(ms/match: scoring and peak search on the rectified patch, CPU time, one thread)")


# -- rendered frames across date gaps, and contrast inversion ------------------------------------
FRAMES_HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0)
INVERSIONS = ("none", "global", "checker")  # how a frame's contrast is reversed


def invert(gray: np.ndarray, how: str) -> np.ndarray:
    """``global``: 255 - image; ``checker``: reversed in every other cell of a 4 x 4 grid (a
    field, roof or pond brighter one year and darker the next, in half of the frame)."""
    if how == "none":
        return gray
    if how == "global":
        return 255 - gray
    h, w = gray.shape
    yy, xx = np.mgrid[0:h, 0:w]
    cells = (yy * 4 // h + xx * 4 // w) % 2 == 0
    return np.where(cells, 255 - gray, gray).astype(np.uint8)


def matchers(reference: Any, home: GeoPoint) -> dict[str, MapMatcher]:
    """Each registered map-matching method's matcher (correlator and gate) on one map."""
    from air_sitl.localize import METHODS
    from air_sitl.localize.mapmatch import MapMatchLocalizer

    out = {}
    for name, factory in METHODS.items():
        loc = factory()
        if isinstance(loc, MapMatchLocalizer):
            out[name] = MapMatcher(reference, CameraModel(), home, **loc.matcher_options())
    return out


def rendered_frames(
    maps: list[str], dates: list[int], heights: list[float], count: int, inversions: list[str]
) -> list[dict[str, Any]]:
    """Frames of date k rendered at random places, headings, roll and pitch up to 5 degrees,
    matched against date 0 from a prior 10-30 m off (right) and 400 m off (wrong) by each
    map-matching method's matcher; one figure line per (map, date gap, height, inversion,
    method). The same-date rows are the gate's control (see ``--calibrate``)."""
    from air_sitl.camera.render import Renderer, pose_state
    from air_sitl.frames import ned2geodetic
    from air_sitl.localize.decode import decode_gray
    from air_sitl.maps import open_map

    home, out = FRAMES_HOME, []
    print(f"{'map':6s} {'gap':6s} {'h m':>5s} {'inverted':8s} {'method':15s} {'ok<5m':>6s} "
          f"{'acc>5m':>6s} {'resp':>5s} {'wrong acc':>9s} {'ms/frame':>8s}")  # fmt: skip
    for kind in maps:
        reference = open_map(kind, home, seed=0, date=0)
        by_method = matchers(reference, home)
        for date in dates:
            renderer = Renderer(open_map(kind, home, seed=0, date=date), CameraModel(), seed=0)
            for height in heights:
                rng = np.random.default_rng(1000 * date + int(height))
                frames = []
                for k in range(count):
                    e, n = (float(v) for v in rng.uniform(-1500.0, 1500.0, 2))
                    roll, pitch = (math.radians(float(v)) for v in rng.uniform(-5.0, 5.0, 2))
                    yaw = float(rng.uniform(-math.pi, math.pi))
                    lat, lon, _ = ned2geodetic(n, e, 0.0, home.lat_deg, home.lon_deg, 0.0)
                    st = pose_state(lat, lon, home.alt_amsl_m + height, alt_agl_m=height,
                                    roll_rad=roll, pitch_rad=pitch, yaw_rad=yaw)  # fmt: skip
                    jpeg, _ = renderer.frame_jpeg(st, k, warn=False)
                    dist = float(rng.uniform(10.0, 30.0))
                    ang = float(rng.uniform(-math.pi, math.pi))
                    prior = (e + dist * math.cos(ang), n + dist * math.sin(ang))
                    frames.append((decode_gray(jpeg, 1), st.q_body_to_ned_wxyz, e, n, prior))
                for how in inversions:
                    for name, matcher in by_method.items():
                        fig = _match_frames(matcher, frames, height, how)
                        fig.update(map=kind, gap=f"0->{date}", height_m=height, inverted=how,
                                   method=name)  # fmt: skip
                        out.append(fig)
                        print(f"{kind:6s} {fig['gap']:6s} {height:5.0f} {how:8s} {name:15s} "
                              f"{fig['ok_5m']:6.2f} {fig['accepted_off_5m']:6.2f} "
                              f"{fig['median_response']:5.2f} {fig['wrong_accepted']:9.2f} "
                              f"{fig['ms_per_frame']:8.1f}", flush=True)  # fmt: skip
    return out


def _match_frames(
    matcher: MapMatcher, frames: list[Any], height: float, how: str
) -> dict[str, Any]:
    ok = off = wrong_acc = 0
    responses, wrong = [], []
    cpu = 0.0
    for gray, q, e, n, (pe, pn) in frames:
        img = invert(gray, how)
        for shift in (0.0, WRONG_OFFSET_M):  # the map's tiles made before timing, not by the first
            matcher.rectify(img, q, height, pe + shift, pn, 35.0)
        c0 = time.process_time()
        res = matcher.match(img, q, height, pe, pn, 35.0)
        cpu += time.process_time() - c0
        if res is not None:
            right = math.hypot(res.east_m - e, res.north_m - n) < RIGHT_M
            ok += int(res.accepted and right)
            off += int(res.accepted and not right)
            responses.append(res.response)
        bad = matcher.match(img, q, height, pe + WRONG_OFFSET_M, pn, 35.0)
        if bad is not None:
            wrong_acc += int(bad.accepted)
            wrong.append((bad.response, bad.peak_ratio))
    total = len(frames)
    return {
        "frames": total,
        "ok_5m": ok / total,
        "accepted_off_5m": off / total,
        "median_response": float(np.median(responses)) if responses else math.nan,
        "wrong_accepted": wrong_acc / total,
        "wrong_response_ratio": wrong,
        "ms_per_frame": 1e3 * cpu / total,
    }


def calibrate(figures: list[dict[str, Any]]) -> None:
    """The gate of each method matched to ``mapmatch``'s on the same-date control: the
    response and peak-ratio thresholds at which the same share of wrong places (400 m off)
    passes each test alone as passes ``mapmatch``'s (MIN_RESPONSE, MAX_PEAK_RATIO)."""
    from air_sitl.localize import mapmatch_core as core

    control = [f for f in figures if f["gap"] == "0->0" and f["inverted"] == "none"]
    pooled: dict[str, np.ndarray] = {}
    for f in control:
        arr = np.array(f["wrong_response_ratio"], dtype=np.float64).reshape(-1, 2)
        pooled[f["method"]] = np.vstack([pooled.get(f["method"], np.empty((0, 2))), arr])
    base = pooled.get("mapmatch")
    if base is None or not base.size:
        return
    pass_resp = float(np.mean(base[:, 0] >= core.MIN_RESPONSE))
    pass_ratio = float(np.mean(base[:, 1] <= core.MAX_PEAK_RATIO))
    p95 = float(np.quantile(base[:, 0], 0.95))
    times = core.MIN_RESPONSE / p95
    print(f"same-date control, wrong places: {len(base)} per method; mapmatch's gate passes "
          f"{pass_resp:.3f} of them on response >= {core.MIN_RESPONSE} ({times:.2f} x their "
          f"p95), {pass_ratio:.3f} on peak ratio <= {core.MAX_PEAK_RATIO}")  # fmt: skip
    for name, arr in pooled.items():
        # Wrong places rarely pass mapmatch's response test on the control (a quantile there
        # is the sample's maximum): the threshold keeps the same multiple of their p95.
        resp = times * float(np.quantile(arr[:, 0], 0.95))
        ratio = float(np.quantile(arr[:, 1], pass_ratio))
        print(f"  {name:15s} matched: min response {resp:.3f}, max peak ratio {ratio:.3f} "
              f"(wrong places: response p50 {np.median(arr[:, 0]):.3f} p95 "
              f"{np.quantile(arr[:, 0], 0.95):.3f} max {arr[:, 0].max():.3f}; peak ratio p5 "
              f"{np.quantile(arr[:, 1], 0.05):.3f})")  # fmt: skip


# -- the methods, end to end ------------------------------------------------------------------
def _make(method: str) -> Localizer:
    from air_sitl.localize import METHODS

    return METHODS[method]()


def run_methods(
    archives: list[Path], methods: list[str], limit: int | None
) -> list[dict[str, Any]]:
    """Score each method on each archive; print one line each; return the figures."""
    import itertools

    from air_sitl.localize.output import write_estimates

    out = []
    print(f"{'archive':8s} {'method':14s} {'median':>6s} {'p95':>6s} {'max':>6s} {'rec@25':>6s} "
          f"{'avail':>6s} {'>50m':>6s} {'fixes':>6s} {'fps cpu':>7s} {'fps wall':>8s}")  # fmt: skip
    for archive in archives:
        truth = _truth(archive)
        for method in methods:
            loc = _make(method)
            with open_archive(archive) as arch:
                context = context_of(arch)
                source = observations(arch, needs_image=loc.needs_image)
                if limit is not None:
                    source = itertools.islice(source, limit)
                c0, w0 = time.process_time(), time.perf_counter()
                est = run_method(loc, context, source, total=len(arch))
                cpu, wall = time.process_time() - c0, time.perf_counter() - w0
            if limit is None:
                write_estimates(archive, method, est, context.home)
            err = np.array([
                math.inf if e.enu_m is None
                else math.hypot(e.enu_m[0] - float(r["east_m"]), e.enu_m[1] - float(r["north_m"]))
                for e, r in zip(est, truth, strict=False)
            ])  # fmt: skip
            fin = err[np.isfinite(err)]
            fig = {
                "archive": archive.name,
                "method": method,
                "frames": len(err),
                "median_m": float(np.median(fin)),
                "p95_m": float(np.percentile(fin, 95)),
                "max_m": float(fin.max()),
                "recall_25m": float(np.mean(err <= 25.0)),
                "availability": len(fin) / len(err),
                "over_50m": float(np.mean(err > 50.0)),
                "fix_share": float(np.mean([bool(e.fix) for e in est])),
                "fps_cpu": len(err) / cpu,
                "fps_wall": len(err) / wall,
            }
            out.append(fig)
            print(f"{archive.name:8s} {method:14s} {fig['median_m']:6.2f} {fig['p95_m']:6.2f} "
                  f"{fig['max_m']:6.2f} {fig['recall_25m']:6.3f} {fig['availability']:6.3f} "
                  f"{fig['over_50m']:6.3f} {fig['fix_share']:6.3f} {fig['fps_cpu']:7.0f} "
                  f"{fig['fps_wall']:8.0f}", flush=True)  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("archives", nargs="*", type=Path)
    parser.add_argument("--correlators", action="store_true")
    parser.add_argument("--methods", action="store_true")
    parser.add_argument(
        "--method", action="append", default=None, help="mapmatch, mapmatch-axial, fused"
    )
    parser.add_argument("--step", type=int, default=100, help="correlators: every n-th frame")
    parser.add_argument("--limit", type=int, default=None, help="methods: first n frames")
    parser.add_argument("--json", type=Path, default=None, help="methods: figures as JSON")
    parser.add_argument("--frames", action="store_true", help="rendered frames across gaps")
    parser.add_argument("--maps", default="urban,forest", help="frames: maps")
    parser.add_argument("--dates", default="0,1,2", help="frames: flight dates (vs date 0)")
    parser.add_argument("--heights", default="200,300", help="frames: heights (m)")
    parser.add_argument("--count", type=int, default=40, help="frames: per map, date, height")
    parser.add_argument("--inversions", default=",".join(INVERSIONS), help="frames: none,...")
    parser.add_argument("--calibrate", action="store_true", help="frames: matched gates")
    args = parser.parse_args(argv)
    cv2.setNumThreads(1)
    if args.frames:
        figures = rendered_frames(
            args.maps.split(","), [int(d) for d in args.dates.split(",")],
            [float(h) for h in args.heights.split(",")], args.count,
            args.inversions.split(","),
        )  # fmt: skip
        if args.calibrate:
            calibrate(figures)
        if args.json is not None:
            for f in figures:
                f.pop("wrong_response_ratio")
            args.json.write_text(json.dumps(figures, indent=1))
        return 0
    if not (args.correlators or args.methods):
        args.correlators = args.methods = True
    if args.correlators:
        correlators(args.archives, args.step)
    if args.methods:
        methods = args.method or ["mapmatch", "mapmatch-axial", "fused"]
        figures = run_methods(args.archives, methods, args.limit)
        if args.json is not None:
            args.json.write_text(json.dumps(figures, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
