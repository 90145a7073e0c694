"""Camera speed and memory: per-frame cost vs JPEG alone, threaded frames/s, RSS over a big COG.

Run: ``python benchmarks/bench_camera.py [--frames N] [--cog /tmp/bench40k.tif]``. Prints:

1. one core: render + noise + JPEG per frame at 200 m, 300 m and 3000 m over ``urban`` (tiles
   warm), beside JPEG encoding alone of the same frames in the same run, and their ratio
   (target <= 2.5); plus the first pass, which also generates the tiles of new ground;
2. the threaded camera bridge (FrameSource) in frames/s with 1 and 2 workers;
3. resident memory while flying over a 40,000 x 40,000 pixel COG (built with
   ``air-sitl map make urban --size-m 24000 24000`` when missing; target < 1 GB);
4. relief (exact first hits): render cost per frame (geometry + pixels + noise) beside the
   flat render of the same frames (the floor), in wall time and in the process's CPU time
   (one render thread), the frames/s of each (the CPU figure is per core; target >= 50,
   real time at 50 Hz) and the CPU ratio to the floor, at 200, 300 and 3000 m over ``urban`` and
   ``forest`` with ``--dem builtin``, and over ``urban`` with a GeoTIFF DSM (the built-in
   urban surface written at 1.2 m, like a lidar DSM; ``--dsm``, built when missing)
   (``--relief-only`` runs just this part);
5. camera effects (issue 34): render + noise + JPEG per frame (``Renderer.frame_jpeg``) with
   every effect on (blur, rolling-shutter, vignette, exposure, haze, distortion) beside the
   plain frame of the same states (the floor), CPU time of the process (one render thread),
   best of 3 passes, at 200 and 300 m in straight flight (18 m/s, a gentle roll) and in a
   45 deg/s roll; target ratio <= 2 (``--effects-only`` runs just this part).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.camera.bridge import CameraBridge
from air_sitl.camera.effects import CameraEffects
from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import ned2geodetic
from air_sitl.maps.base import MapSource
from air_sitl.maps.open import open_map, open_surface
from air_sitl.state import GeoPoint, VehicleState, mission_sample

REPEATS = 5
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


def rss_mb() -> float:
    """Resident set size of this process, MB (Linux /proc)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def path_states(
    alt_m: float, n: int, *, speed_m_s: float = 15.0, east0_m: float = 0.0
) -> list[VehicleState]:
    """A 50 Hz straight flight north with a gentle roll oscillation, like AIR's lines."""
    out = []
    for i in range(n):
        north = speed_m_s * i / 50.0
        lat, lon, _ = ned2geodetic(north, east0_m, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        out.append(
            pose_state(
                lat,
                lon,
                HOME.alt_amsl_m + alt_m,
                alt_agl_m=alt_m,
                roll_rad=math.radians(5.0) * math.sin(i / 40.0),
                pitch_rad=math.radians(2.0),
                yaw_rad=0.02,
                sim_time_ns=i * 20_000_000,
            )
        )
    return out


def one_core(frames: int) -> None:
    """Per-frame cost of the pipeline vs JPEG only, same frames, same run."""
    cv2.setNumThreads(1)
    alts = (200.0, 300.0, 3000.0)
    print(
        "1) one core, urban map, 640x480, q90, noise sigma 1.8 "
        f"(median CPU ms per frame, best of {REPEATS} passes)"
    )
    print("   'flying': first pass, generating the new ground's tiles; then the same frames warm")
    print(
        f"{'alt m':>6} {'flying':>7} {'geometry':>8} {'pixels':>7} {'jpeg':>6} {'whole':>7}"
        f" {'jpeg-only':>9} {'ratio':>6} {'passes':>11}"
    )
    print("   (pixels: the warp with the noise added strip by strip, as Renderer.frame_jpeg runs)")
    renderers, paths, cold = [], [], []
    for alt in alts:
        renderer = Renderer(open_map("urban", HOME, seed=0), CameraModel(), seed=0)
        states = path_states(alt, frames)
        renderer.render(states[0])  # the ground under the start point, untimed
        t0 = time.thread_time()
        for i, s in enumerate(states):  # in flight: new ground (tiles) arrives at 15 m/s
            renderer.frame_jpeg(s, i)
        cold.append((time.thread_time() - t0) / frames * 1e3)
        renderers.append(renderer)
        paths.append(states)
    # Warm passes; JPEG-only is timed right after each frame's pipeline, on the same frame.
    # CPU time of this thread (cv2 runs single-threaded in it): other processes sharing the
    # 2 cores stretch wall time, not the cost measured here. This VM's host still slows the
    # memory-bound steps (warp, noise) by up to 2x for seconds at a time while leaving the
    # cache-resident JPEG encoder alone, so the passes of the three altitudes alternate
    # (spread over the run) and each figure is the best of REPEATS medians, as timeit does.
    runs: list[list[npt.NDArray[np.float64]]] = [[] for _ in alts]
    for _ in range(REPEATS):
        for k, (renderer, states) in enumerate(zip(renderers, paths, strict=True)):
            parts = np.zeros((frames, 4))
            for i, s in enumerate(states):
                a = time.thread_time()
                g = renderer.geometry(s)
                b = time.thread_time()
                img = renderer.render(s, g, noise_index=i)
                c = time.thread_time()
                renderer.encode(img)
                d = time.thread_time()
                renderer.encode(img)
                e = time.thread_time()
                parts[i] = (b - a, c - b, d - c, e - d)
            runs[k].append(parts)
    for alt, flying, alt_runs in zip(alts, cold, runs, strict=True):
        parts = min(alt_runs, key=lambda p: float(np.median(p[:, :3].sum(axis=1))))
        med = np.median(parts, axis=0) * 1e3
        whole = float(np.median(parts[:, :3].sum(axis=1))) * 1e3
        each = sorted(float(np.median(p[:, :3].sum(axis=1)) / np.median(p[:, 3])) for p in alt_runs)
        print(
            f"{alt:6.0f} {flying:7.2f} {med[0]:8.2f} {med[1]:7.2f} {med[2]:6.2f} {whole:7.2f}"
            f" {med[3]:9.2f} {whole / med[3]:6.2f} {each[0]:5.2f}-{each[-1]:<5.2f}"
        )
    print("   (passes: the ratio of each pass, lowest to highest: the host's effect on this run)")


def threaded(frames: int) -> None:
    """Frames/s of the CameraBridge FrameSource (tiles warm), 1 and 2 workers."""
    cv2.setNumThreads(1)
    print("2) camera bridge (FrameSource), 300 m, tiles warm")
    renderer = Renderer(open_map("urban", HOME, seed=0), CameraModel(), seed=0)
    samples = [mission_sample(s) for s in path_states(300.0, frames)]
    for s in samples[:: max(1, frames // 50)]:
        renderer.render(s.state)
    for workers in (1, 2):
        bridge = CameraBridge(renderer, workers=workers, max_pending=16)
        t0 = time.perf_counter()
        got = 0
        for i, s in enumerate(samples):
            bridge.submit(s, i)
            got += len(bridge.ready())
        got += len(bridge.flush())
        dt = time.perf_counter() - t0
        bridge.close()
        print(f"   workers {workers}: {got / dt:7.1f} frames/s ({got} frames)")


def big_cog(cog: Path, frames: int) -> None:
    """Resident memory while flying over a 40,000 x 40,000 px COG at 300 m and 3000 m."""
    print(f"3) memory over {cog}")
    if not cog.exists():
        print("   building it with air-sitl map make (once; several minutes)...", flush=True)
        subprocess.run(
            [sys.executable, "-m", "air_sitl", "map", "make", "urban", "--out", str(cog),
             "--size-m", "24000", "24000", "--origin", f"{HOME.lat_deg},{HOME.lon_deg}"],
            check=True,
        )  # fmt: skip
    start = rss_mb()
    m = open_map(str(cog), HOME)
    w, h = m.georef.width_px, m.georef.height_px
    print(
        f"   {w} x {h} px, {cog.stat().st_size / 1e6:.0f} MB on disk, RSS at start {start:.0f} MB"
    )
    renderer = Renderer(m, CameraModel(), seed=0)
    peak = start
    t0 = time.perf_counter()
    count = 0
    # A lawnmower at 300 m over 10 km x 8 km (rows 400 m apart, 40 m between frames: every
    # frame sees new ground), then a 3000 m line: far more tiles than the cache holds.
    for row in range(20):
        east = -5000.0 + 400.0 * row
        for i, s in enumerate(path_states(300.0, frames, speed_m_s=2000.0, east0_m=east)):
            renderer.frame_jpeg(s, count)
            count += 1
            if i % 25 == 0:
                peak = max(peak, rss_mb())
    for i, s in enumerate(path_states(3000.0, frames, speed_m_s=1000.0, east0_m=-3000.0)):
        renderer.frame_jpeg(s, count)
        count += 1
        if i % 25 == 0:
            peak = max(peak, rss_mb())
    dt = time.perf_counter() - t0
    cache_mb = m.cache_bytes / 1e6  # type: ignore[attr-defined]
    print(
        f"   {count} frames ({count / dt:.0f} frames/s, new ground every frame), tile cache "
        f"{cache_mb:.0f} MB, peak RSS {peak:.0f} MB (target < 1024)"
    )


def relief(frames: int, dsm: Path) -> None:
    """Render cost with relief vs flat, same frames, same run: wall clock and CPU time."""
    cv2.setNumThreads(1)
    print("4) relief vs flat, one render thread (cv2 single-threaded), render + noise, tiles warm")
    print("   wall: elapsed time over the frames (other load on the machine stretches it)")
    print("   CPU: this process's CPU time over the same frames (time.process_time): per core")
    print("   each figure the best of 3 passes; ratio: relief CPU / flat CPU (the floor)")
    head = f"{'map':>7} {'dem':>8} {'alt m':>6} {'wall ms':>13} {'wall fps':>8}"
    print(f"{head} {'CPU ms':>13} {'CPU fps/core':>12} {'ratio':>6}")  # target fps >= 50
    print(f"{'':>23} {'flat':>6} {'relief':>6} {'relief':>8} {'flat':>6} {'relief':>6}")
    for kind, dem in (("urban", "builtin"), ("forest", "builtin"), ("urban", "dsm")):
        m = open_map(kind, HOME, seed=0)
        flat = Renderer(m, CameraModel(), seed=0)
        if dem == "dsm":
            if not dsm.exists():
                write_dsm(dsm, m)
            surface = open_surface(str(dsm), m)
        else:
            surface = open_surface(dem, m)
        rel = Renderer(m, CameraModel(), seed=0, surface=surface)
        for alt in (200.0, 300.0, 3000.0):
            states = path_states(alt, frames)
            for s in states[:: max(1, frames // 10)]:  # generate the tiles, untimed
                rel.render(s)
            wall: list[float] = []
            cpu: list[float] = []
            for renderer in (flat, rel):
                passes = []
                for _ in range(3):
                    w0, c0 = time.perf_counter(), time.process_time()
                    for i, s in enumerate(states):
                        renderer.render(s, noise_index=i)
                    w1, c1 = time.perf_counter(), time.process_time()
                    passes.append(((w1 - w0) / frames * 1e3, (c1 - c0) / frames * 1e3))
                wall.append(min(p[0] for p in passes))
                cpu.append(min(p[1] for p in passes))
            print(
                f"{kind:>7} {dem:>8} {alt:6.0f} {wall[0]:6.2f} {wall[1]:6.2f} {1e3 / wall[1]:8.1f}"
                f" {cpu[0]:6.2f} {cpu[1]:6.2f} {1e3 / cpu[1]:12.1f} {cpu[1] / cpu[0]:6.2f}"
            )


ALL_EFFECTS = ("blur", "rolling-shutter", "vignette", "exposure", "haze", "distortion")


def moving_states(alt_m: float, n: int, roll_rate_deg_s: float) -> list[VehicleState]:
    """18 m/s north; a 45 deg/s roll from -20 deg, or a gentle roll oscillation (rates set,
    as the blur and the rolling shutter read them)."""
    out = []
    for i in range(n):
        lat, lon, _ = ned2geodetic(18.0 * i / 50.0, 0.0, 0.0, HOME.lat_deg, HOME.lon_deg, 0.0)
        if roll_rate_deg_s:
            roll = math.radians(-20.0 + roll_rate_deg_s * i / 50.0)
            rates = (math.radians(roll_rate_deg_s), 0.01, 0.02)
        else:
            roll = math.radians(5.0) * math.sin(i / 40.0)
            rates = (math.radians(5.0) * 50.0 / 40.0 * math.cos(i / 40.0), 0.01, 0.02)
        state = pose_state(
            lat, lon, HOME.alt_amsl_m + alt_m, alt_agl_m=alt_m, roll_rad=roll,
            pitch_rad=math.radians(2.0), yaw_rad=0.02, sim_time_ns=i * 20_000_000,
        )  # fmt: skip
        out.append(replace(state, vel_ned_m_s=(18.0, 0.0, 0.0), rate_frd_rad_s=rates))
    return out


def effects(frames: int) -> None:
    """All camera effects vs the plain frame, same states, same run: CPU ms per frame."""
    cv2.setNumThreads(1)
    print(
        "5) camera effects (all six) vs the plain frame: render + noise + JPEG, urban, tiles warm"
    )
    print("   CPU ms per frame of this process (one render thread), best of 3 passes; target <= 2")
    print(f"{'case':>14} {'plain ms':>9} {'effects ms':>10} {'ratio':>6}")
    m = open_map("urban", HOME, seed=0)
    for alt, rate in ((200.0, 0.0), (300.0, 0.0), (200.0, 45.0), (300.0, 45.0)):
        states = moving_states(alt, frames, rate)
        plain = Renderer(m, CameraModel(), seed=0)
        fx = Renderer(m, CameraModel(effects=CameraEffects(enabled=ALL_EFFECTS)), seed=0)
        for s in states[:: max(1, frames // 10)]:  # the tiles and the kernels, untimed
            plain.frame_jpeg(s, 0)
            fx.frame_jpeg(s, 0)
        cpu: list[list[float]] = [[], []]
        for _ in range(3):
            for k, renderer in enumerate((plain, fx)):
                c0 = time.process_time()
                for i, s in enumerate(states):
                    renderer.frame_jpeg(s, i)
                cpu[k].append((time.process_time() - c0) / frames * 1e3)
        a, b = min(cpu[0]), min(cpu[1])
        case = f"{alt:.0f} m " + (f"roll {rate:.0f}/s" if rate else "line")
        print(f"{case:>14} {a:9.2f} {b:10.2f} {b / a:6.2f}")


def write_dsm(path: Path, m: MapSource, half_m: float = 3200.0) -> None:
    """The built-in surface of a procedural map as a GeoTIFF at twice its pixel size."""
    import rasterio
    from rasterio.transform import Affine

    print(f"   writing {path} (once)...", flush=True)
    surface = open_surface("builtin", m)
    assert surface is not None
    hx, hy = m.latlon_to_map_px(HOME.lat_deg, HOME.lon_deg)
    n = round(half_m / m.georef.gsd_m / 2)  # level-1 pixels each side of home
    x0, y0 = round(hx / 2) - n, round(hy / 2) - n
    heights = surface.heights(1, x0, y0, 2 * n, 2 * n)
    _, t1, t2, _, t4, t5 = m.georef.transform
    ex, ey = m.georef.px_to_crs(2 * x0 - 0.5, 2 * y0 - 0.5)  # level-1 pixel (x0, y0)'s corner
    with rasterio.open(
        path, "w", driver="GTiff", width=2 * n, height=2 * n, count=1, dtype="float32",
        crs=m.georef.crs, transform=Affine(2 * t1, 2 * t2, ex, 2 * t4, 2 * t5, ey),
        tiled=True, blockxsize=256, blockysize=256, compress="deflate",
    ) as dst:  # fmt: skip
        dst.write(heights, 1)


def main() -> None:
    """Parse options and run the three measurements."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300)
    parser.add_argument("--cog", type=Path, default=Path("/tmp/bench40k.tif"))
    parser.add_argument("--skip-cog", action="store_true")
    parser.add_argument("--only-cog", action="store_true")
    parser.add_argument("--relief-only", action="store_true")
    parser.add_argument("--effects-only", action="store_true")
    parser.add_argument("--dsm", type=Path, default=Path("/tmp/bench_dsm_urban.tif"))
    args = parser.parse_args()
    print(f"RSS at start {rss_mb():.0f} MB")
    if args.relief_only:
        relief(args.frames, args.dsm)
        return
    if args.effects_only:
        effects(args.frames)
        return
    if not args.skip_cog:
        big_cog(args.cog, args.frames)  # first: its RSS is not mixed with the other maps'
    if not args.only_cog:
        one_core(args.frames)
        threaded(args.frames * 2)
        relief(args.frames, args.dsm)
        effects(args.frames)


if __name__ == "__main__":
    main()
