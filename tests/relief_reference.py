"""An independent, slow, obviously correct first-hit march, to check the relief renderer.

Each pixel's ray descends from the top of the window's heights in fine equal steps (at most
1/16 of a level pixel sideways and 1/2000 of the height range each), and the first step that
is not above the bilinear surface of the posts (edges repeated outward) is bisected 40
times. NumPy over all the rays at once; nothing of the renderer's kernels is used.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from air_sitl.camera.relief import HeightWindow

F64 = npt.NDArray[np.float64]


def bilinear(values: F64, x: F64, y: F64) -> F64:
    """Heights at level pixels (x, y) of the window (its heights as float64), edges repeated
    outward."""
    h, w = values.shape
    x, y = np.clip(x, 0.0, w - 1.0), np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(x).astype(np.int64), w - 2)
    y0 = np.minimum(np.floor(y).astype(np.int64), h - 2)
    fx, fy = x - x0, y - y0
    flat, at = values.ravel(), y0 * w + x0  # the posts by flat index: [y0, x0] is at[...]
    gx = 1.0 - fx
    top = flat.take(at) * gx + flat.take(at + 1) * fx
    bottom = flat.take(at + w) * gx + flat.take(at + w + 1) * fx
    out: F64 = top * (1.0 - fy) + bottom * fy
    return out


def reference_hits(
    window: HeightWindow,
    r: tuple[float, ...],
    jac: tuple[float, float, float, float],
    level: int,
    cx: float,
    cy: float,
    cam_z: float,
    u: F64,
    v: F64,
) -> tuple[F64, F64]:
    """Window level-pixel coordinates of the first surface point seen at image points (u, v)
    from a camera at level pixel (cx, cy) (absolute) and altitude cam_z; ``r`` turns an
    image point (u, v, 1) into a NED direction, ``jac`` (north, east) metres into level-0
    map pixels."""
    s = float(1 << level)
    dn = r[0] * u + r[1] * v + r[2]
    de = r[3] * u + r[4] * v + r[5]
    dd = r[6] * u + r[7] * v + r[8]
    assert (dd > 0).all(), "every ray must descend"
    ax = (jac[0] * dn + jac[1] * de) / (s * dd)  # level pixels per metre of descent
    ay = (jac[2] * dn + jac[3] * de) / (s * dd)
    x_cam, y_cam = cx - window.x0, cy - window.y0
    values = window.values.astype(np.float64)  # once, not at each of the march's steps
    z_top, z_bot = min(float(values.max()), cam_z), float(values.min())

    slope = float(np.abs(np.concatenate([ax, ay])).max())
    span = z_top - z_bot
    dz = min(span / 2000.0, 1.0 / (16.0 * slope)) if slope > 0 else span / 2000.0
    hi = np.full(u.shape, z_top)  # the ray is above the surface at hi (or hits at z_top)
    lo = np.full(u.shape, np.nan)
    open_ = _above_at(values, x_cam, y_cam, cam_z, ax, ay, hi)
    hit_at_top = ~open_
    lo[hit_at_top] = z_top
    z = z_top
    while open_.any() and z > z_bot:
        z = max(z - dz, z_bot)
        idx = np.flatnonzero(open_)
        zs = np.full(idx.size, z)
        a = _above_at(values, x_cam, y_cam, cam_z, ax[idx], ay[idx], zs)
        under = idx[~a]
        lo[under] = z
        open_[under] = False
        hi[idx[a]] = z
    lo[open_] = z_bot
    # Bisection between the last altitude above and the first not above.
    todo = ~hit_at_top
    h_, l_ = hi[todo], lo[todo]
    axs, ays = ax[todo], ay[todo]
    for _ in range(40):
        mid = 0.5 * (h_ + l_)
        a = _above_at(values, x_cam, y_cam, cam_z, axs, ays, mid)
        h_ = np.where(a, mid, h_)
        l_ = np.where(a, l_, mid)
    z_hit = lo.copy()
    z_hit[todo] = l_
    return x_cam + (cam_z - z_hit) * ax, y_cam + (cam_z - z_hit) * ay


def _above_at(
    values: F64, x_cam: float, y_cam: float, cam_z: float, ax: F64,
    ay: F64, z: F64,
) -> npt.NDArray[np.bool_]:  # fmt: skip
    x, y = x_cam + (cam_z - z) * ax, y_cam + (cam_z - z) * ay
    out: npt.NDArray[np.bool_] = z > bilinear(values, x, y)
    return out
