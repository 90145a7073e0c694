"""Estimate files for the tests: truth plus offsets and noise, rows dropped, bad cells."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import numpy.typing as npt

import air_sitl.dataset
from air_sitl.eval.sources import load_truth
from air_sitl.eval.trajectory import Truth

HEADER = (
    "sim_time_ns,frame,east_m,north_m,up_m,lat_deg,lon_deg,alt_amsl_m,qw,qx,qy,qz,"
    "latency_wall_ms,latency_frames"
)


def truth_of(archive: Path) -> Truth:
    with air_sitl.dataset.open(archive) as opened:
        return load_truth(opened)


def rows(
    truth: Truth,
    pos: npt.NDArray[np.float64],
    frames: npt.NDArray[np.int64] | None = None,
    latency_ms: npt.NDArray[np.float64] | None = None,
) -> list[str]:
    """CSV rows (recorder format) for ``pos`` at ``frames`` (default: every frame)."""
    idx = np.arange(truth.frames) if frames is None else frames
    out = []
    for k, f in enumerate(idx):
        e, n, u = pos[k]
        lat = "" if latency_ms is None else f"{latency_ms[k]:.3f}"
        cells = ["nan" if not np.isfinite(c) else f"{c:.6f}" for c in (e, n, u)]
        out.append(f"{truth.t_ns[f]},{f},{','.join(cells)},,,,,,,,{lat},0")
    return out


def write_csv(path: Path, lines: list[str], header: str = HEADER) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join([header, *lines]) + "\n", encoding="ascii")
    return path


def write_estimate(
    archive: Path,
    name: str,
    pos: npt.NDArray[np.float64],
    frames: npt.NDArray[np.int64] | None = None,
    latency_ms: npt.NDArray[np.float64] | None = None,
) -> Path:
    """``archive/estimates/<name>.csv`` holding ``pos`` at ``frames``."""
    truth = truth_of(archive)
    return write_csv(archive / "estimates" / f"{name}.csv", rows(truth, pos, frames, latency_ms))
