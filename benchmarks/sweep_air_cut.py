"""``bench_sweep.py --air-cut``: a cut of the AIR sweep example, this code against the code before.

One scenario x map dates 0, 1, 2 x altitude offset 0 x seed 1 of ``examples/air_sweep.yaml``
(mapmatch and vo against date 0), swept by ``air-sitl sweep`` in a process of its own with
``-j 1`` and ``-j 2``: first by the code in ``--base-code`` (the floor: the commit before,
which flies every date), then by this code (the dates flown once). Printed: wall and CPU (the
sweep process and its workers) of each, the ratio to the floor, this code's ``time_s`` parts
per capture frame, each method's localize timed alone over every date's archive, and the
108-run sweep estimated from those parts.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "air_sweep.yaml"
# AIR's table 2 (frames at 50 Hz): what the 108-run sweep captures per scenario at 200 m.
AIR_FRAMES = {"FL-200": 11837, "FR-200": 16056, "FC-200": 3601,
              "UL-200": 8735, "UR-200": 14997, "UC-200": 3422}  # fmt: skip
ALTITUDES, SEEDS, DATES = 2, 3, 3


def _cpu_children_s() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def _write_cut(folder: Path, scenario: str) -> Path:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    data["axes"] = {"scenario": [scenario], "map-date": [0, 1, 2], "altitude-offset": [0],
                    "seed": [1]}  # fmt: skip
    path = folder / "air_cut.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _sweep(code: Path, spec: Path, out: Path, jobs: int) -> tuple[float, float]:
    """One ``air-sitl sweep`` run by the code in ``code``: (wall s, CPU s with its workers)."""
    env = {**os.environ, "PYTHONPATH": str(code)}
    cmd = [sys.executable, "-m", "air_sitl", "sweep", str(spec), "--out", str(out),
           "-j", str(jobs), "--quiet"]  # fmt: skip
    cpu = _cpu_children_s()
    start = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, cwd=code)
    return time.perf_counter() - start, _cpu_children_s() - cpu


def _rows(out: Path) -> list[dict[str, Any]]:
    lines = (out / "results.jsonl").read_text(encoding="utf-8").splitlines()
    rows = [json.loads(line) for line in lines if line.strip()]
    bad = [r["error"] for r in rows if r.get("error")]
    if bad:
        sys.exit(f"bench_sweep --air-cut: a run failed: {bad[0]}")
    return rows


def _localize_alone(out: Path, rows: list[dict[str, Any]]) -> dict[str, float]:
    """Each method run alone (in this process) over every date's archive, then both in one
    pass as a sweep's worker runs them (its reference map kept from archive to archive): CPU
    s per frame."""
    sys.path.insert(0, str(ROOT))
    from air_sitl.localize.archive import run_archive, run_archive_methods
    from air_sitl.sweep.run import reference_map

    took: dict[str, float] = {}
    frames = 0
    methods = ("mapmatch", "vo")
    for row in rows:
        archive = out / row["archive"]
        frames += int(row["summary"]["capture_frames"])
        for method in methods:
            start = time.process_time()
            run_archive(archive, method, name=f"{method}-again", reference_date=0, seed=1)
            took[method] = took.get(method, 0.0) + time.process_time() - start
        start = time.process_time()
        run_archive_methods(
            archive,
            [(m, f"{m}-pass", {}) for m in methods],
            reference_date=0,
            seed=1,
            open_map=reference_map,
        )
        took["one pass"] = took.get("one pass", 0.0) + time.process_time() - start
    return {m: s / frames for m, s in took.items()}


def _same_estimates(before: Path, after: Path, rows: list[dict[str, Any]]) -> None:
    """Each run's estimates files of this code against the code before's: the same bytes?"""
    same = differ = 0
    for row in rows:
        for path in sorted((after / row["archive"] / "estimates").glob("*.csv")):
            old = before / row["archive"] / "estimates" / path.name
            if old.read_bytes() == path.read_bytes():
                same += 1
            else:
                differ += 1
                print(f"  estimates differ: {row['archive']}/estimates/{path.name}")
    print(f"estimates files identical to the code before's: {same} of {same + differ}")


def _parts(label: str, jobs: int, rows: list[dict[str, Any]]) -> tuple[dict[str, float], int]:
    """The rows' ``time_s`` parts summed (wall s), printed per capture frame."""
    frames = sum(int(r["summary"]["capture_frames"]) for r in rows)
    parts: dict[str, float] = {}
    for row in rows:
        for part, seconds in row["time_s"].items():
            parts[part] = parts.get(part, 0.0) + float(seconds)
    text = ", ".join(f"{k} {v:.1f} s ({1000 * v / frames:.2f} ms)" for k, v in parts.items())
    print(f"{label} -j {jobs}, {len(rows)} runs, {frames} frames; time_s (per frame): {text}")
    return parts, frames


def air_cut(scenario: str, base_code: Path | None, jobs_list: tuple[int, ...] = (1, 2)) -> None:
    """Measure and print (see the module docstring); ``jobs_list``: the ``-j`` values."""
    if base_code is None:
        sys.exit("bench_sweep --air-cut: give --base-code DIR (the code before, the floor)")
    print(f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    with tempfile.TemporaryDirectory(prefix="bench-air-cut-") as tmp:
        root = Path(tmp)
        spec = _write_cut(root, scenario)
        figures: dict[tuple[str, int], tuple[float, float]] = {}
        for label, code in (("before", base_code.resolve()), ("after", ROOT)):
            for jobs in jobs_list:
                figures[label, jobs] = _sweep(code, spec, root / f"{label}-j{jobs}", jobs)
                wall, cpu = figures[label, jobs]
                print(f"{label:6s} -j {jobs}: {wall:7.1f} s wall, {cpu:7.1f} s CPU "
                      f"(load {os.getloadavg()[0]:.1f})")  # fmt: skip
        for jobs in jobs_list:
            (bw, bc), (aw, ac) = figures["before", jobs], figures["after", jobs]
            print(f"-j {jobs}: after / before: wall {aw / bw:.2f}x, CPU {ac / bc:.2f}x")
        first = jobs_list[0]
        _parts("before", first, _rows(root / f"before-j{first}"))
        rows = _rows(root / f"after-j{first}")
        parts, frames = _parts("after", first, rows)
        # The parts are wall seconds of a worker sharing the cores with whatever else runs:
        # scaled by the sweep's CPU over its wall, they are CPU seconds.
        cores = figures["after", first][1] / max(sum(parts.values()), 1e-9)
        print(f"after -j {first} used {cores:.2f} cores in its runs (CPU / the parts' wall)")
        _same_estimates(root / f"before-j{first}", root / f"after-j{first}", rows)
        alone = _localize_alone(root / f"after-j{first}", rows)
        text = ", ".join(f"{m} {1000 * s:.2f} ms" for m, s in alone.items())
        print(f"localize alone, CPU per frame over the three dates: {text}")
        alone.pop("one pass")
        _estimate({k: v * cores for k, v in parts.items()}, frames, alone)
    print(f"load average after: {os.getloadavg()[0]:.2f}")


def _estimate(parts: dict[str, float], frames: int, alone: dict[str, float]) -> None:
    """The 108-run sweep from the cut's parts (CPU s) per frame of a run: every run's frames at
    these costs (the flight's share as the cut's, each date's render, localize and eval once
    per run), on two cores."""
    per_run_frames = sum(AIR_FRAMES.values()) * ALTITUDES * SEEDS  # per map date
    total_frames = per_run_frames * DATES
    rates = {k: v / frames for k, v in parts.items()}  # s per frame of a run
    seconds = {k: rate * total_frames for k, rate in rates.items()}
    whole = sum(seconds.values())
    text = ", ".join(f"{k} {v / 3600:.2f} h" for k, v in seconds.items())
    print(
        f"108-run estimate: {total_frames:,} frames of runs; CPU {whole / 3600:.2f} h "
        f"({text}); on -j 2 about {whole / 2 / 3600:.2f} h of wall on two free cores "
        "(target 1 h: 7,200 s of CPU, "
        f"{7200 / total_frames * 1000:.2f} ms per frame of a run)"
    )
    for method, rate in alone.items():
        print(f"  localize {method} alone: {rate * total_frames / 3600:.2f} h of CPU")
