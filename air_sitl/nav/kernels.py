"""Compiled numerics of the error-state EKF: covariance prediction and measurement updates.

Each is one call where numpy needed five to ten (a numpy call on a 17x17 array costs about
a microsecond, and its machinery crowds the caches the rest of the step runs from). P is
updated in place; a measurement update also writes its correction into ``dx`` and adds it to
``pending`` (what the output predictor has not taken yet), and returns its test ratio and
whether it was fused: ``(inf, False)`` when the innovation covariance is unusable, ``(ratio,
False)`` when the gate rejects it (``force`` skips the gate). The caller injects ``dx`` into
the nominal state (``ErrorStateEkf.inject``).

Sums run in index order; no fastmath, so every run gives the same bits.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Matrix = npt.NDArray[np.float64]


@compiled
def _f_times(M: Matrix, cols: npt.NDArray[np.int64], vals: Matrix) -> Matrix:
    """F M for F = I + the off-diagonal entries (``cols``, ``vals``: per row, -1 ends)."""
    n = M.shape[0]
    out = M.copy()
    for i in range(n):
        for e in range(cols.shape[1]):
            c = cols[i, e]
            if c < 0:
                break
            f = vals[i, e]
            for j in range(n):
                out[i, j] += f * M[c, j]
    return out


@compiled
def predict_covariance(
    P: Matrix, r: tuple[float, ...], T: float, dvx: float, dvy: float, dvz: float,
    q_diag: Matrix,
) -> None:  # fmt: skip
    """P = F P F' + diag(q) over a step of ``T`` s, symmetrised; ``r`` is the body->NED
    rotation (row-major, 9 floats), ``dv`` the NED specific-force delta velocity of the step.

    F is the identity plus: position-velocity T; position-attitude -[T dv / 2]x;
    velocity-attitude -[dv]x; velocity-accel bias and attitude-gyro bias -R T.
    """
    n = P.shape[0]
    hx, hy, hz = 0.5 * T * dvx, 0.5 * T * dvy, 0.5 * T * dvz
    # The off-diagonal entries of F by row: (column, value) pairs, at most 6 a row.
    cols = np.full((n, 6), -1, dtype=np.int64)
    vals = np.zeros((n, 6))
    entries = (
        (0, 3, T), (0, 7, hz), (0, 8, -hy), (1, 4, T), (1, 6, -hz), (1, 8, hx),
        (2, 5, T), (2, 6, hy), (2, 7, -hx), (3, 7, dvz), (3, 8, -dvy), (4, 6, -dvz),
        (4, 8, dvx), (5, 6, dvy), (5, 7, -dvx),
    )  # fmt: skip
    used = np.zeros(n, dtype=np.int64)
    for row, col, value in entries:
        cols[row, used[row]] = col
        vals[row, used[row]] = value
        used[row] += 1
    for i in range(3):
        for j in range(3):
            m = -r[3 * i + j] * T
            cols[3 + i, 2 + j] = 12 + j  # after the velocity rows' two attitude entries
            vals[3 + i, 2 + j] = m
            cols[6 + i, j] = 9 + j
            vals[6 + i, j] = m
    # F P F' = F (F P)' (F P is A, A' its transpose): F applied to rows, twice.
    B = _f_times(_f_times(P, cols, vals).T, cols, vals)  # = (A F')', transposed back below
    for i in range(n):
        B[i, i] += q_diag[i]
    for i in range(n):
        for j in range(i, n):
            s = 0.5 * (B[j, i] + B[i, j])
            P[i, j] = s
            P[j, i] = s


@compiled
def _update(
    P: Matrix, pht: Matrix, s: float, innovation: float, gate: float, force: bool,
    dx: Matrix, pending: Matrix,
) -> tuple[float, bool]:  # fmt: skip
    """The gate and update of one scalar measurement: ``pht`` = P h' (a copy), ``s`` =
    h P h' + R."""
    if not (s > 0.0 and math.isfinite(s)):
        return math.inf, False
    ratio = innovation * innovation / (s * gate * gate)
    if ratio > 1.0 and not force:
        return ratio, False
    n = P.shape[0]
    inv = 1.0 / s
    for i in range(n):
        k = pht[i] * inv
        for j in range(n):
            P[i, j] -= k * pht[j]
        dx[i] = k * innovation
        pending[i] += dx[i]
    return ratio, True


@compiled
def fuse_column(
    P: Matrix, first: int, R: float, innovation: float, gate: float, force: bool,
    dx: Matrix, pending: Matrix,
) -> tuple[float, bool]:  # fmt: skip
    """One scalar measurement of the error state ``first`` (H selects it)."""
    pht = P[:, first].copy()
    return _update(P, pht, pht[first] + R, innovation, gate, force, dx, pending)  # type: ignore[no-any-return]


@compiled
def fuse_row(
    P: Matrix, h: Matrix, R: float, innovation: float, gate: float, force: bool,
    dx: Matrix, pending: Matrix,
) -> tuple[float, bool]:  # fmt: skip
    """One scalar measurement with the dense Jacobian row ``h``."""
    n = P.shape[0]
    pht = np.zeros(n)
    for i in range(n):
        acc = 0.0
        for j in range(n):
            hj = h[j]
            if hj != 0.0:
                acc += P[i, j] * hj
        pht[i] = acc
    s = R
    for i in range(n):
        s += h[i] * pht[i]
    return _update(P, pht, s, innovation, gate, force, dx, pending)  # type: ignore[no-any-return]


@compiled
def fuse_block(
    P: Matrix, first: int, y: Matrix, R: Matrix, gate: float, force: bool,
    dx: Matrix, pending: Matrix,
) -> tuple[float, bool]:  # fmt: skip
    """A vector measurement (2 or 3) of the error states ``first ..``, R its covariance:
    S = P[first.., first..] + R inverted in closed form (refused unless positive)."""
    m = y.shape[0]
    n = P.shape[0]
    S = np.empty((m, m))
    for a in range(m):
        for b in range(m):
            S[a, b] = P[first + a, first + b] + R[a, b]
    Si = np.empty((m, m))
    if m == 2:
        a_, b_, d_ = S[0, 0], S[0, 1], S[1, 1]
        det = a_ * d_ - b_ * b_
        if not (a_ > 0.0 and det > 0.0):
            return math.inf, False
        Si[0, 0], Si[0, 1] = d_ / det, -b_ / det
        Si[1, 0], Si[1, 1] = -b_ / det, a_ / det
    else:
        a_, b_, c_ = S[0, 0], S[0, 1], S[0, 2]
        e_, f_, i_ = S[1, 1], S[1, 2], S[2, 2]
        c00 = e_ * i_ - f_ * f_
        c01 = c_ * f_ - b_ * i_
        c02 = b_ * f_ - c_ * e_
        det = a_ * c00 + b_ * c01 + c_ * c02
        if not (a_ > 0.0 and det > 0.0):
            return math.inf, False
        rd = 1.0 / det
        Si[0, 0], Si[0, 1], Si[0, 2] = c00 * rd, c01 * rd, c02 * rd
        Si[1, 0], Si[1, 1], Si[1, 2] = c01 * rd, (a_ * i_ - c_ * c_) * rd, (b_ * c_ - a_ * f_) * rd
        Si[2, 0], Si[2, 1], Si[2, 2] = c02 * rd, Si[1, 2], (a_ * e_ - b_ * b_) * rd
    w = np.zeros(m)
    for a in range(m):
        for b in range(m):
            w[a] += Si[a, b] * y[b]
    d2 = 0.0
    for a in range(m):
        d2 += y[a] * w[a]
    if not (d2 >= 0.0 and math.isfinite(d2)):
        return math.inf, False
    ratio = d2 / (gate * gate)
    if ratio > 1.0 and not force:
        return ratio, False
    pht = P[:, first : first + m].copy()
    K = np.zeros((n, m))  # P H' S^-1
    for i in range(n):
        acc = 0.0
        for a in range(m):
            acc += pht[i, a] * w[a]
            for b in range(m):
                K[i, b] += pht[i, a] * Si[a, b]
        dx[i] = acc
        pending[i] += acc
    for i in range(n):
        for j in range(n):
            acc = 0.0
            for b in range(m):
                acc += K[i, b] * pht[j, b]
            P[i, j] -= acc
    return ratio, True


@functools.cache
def warm() -> None:
    """Compile every kernel now (or load it from numba's disk cache): a flight's filter calls
    this when it is built, before the clock runs, so the first measurement update does not
    stall the simulation thread mid-flight (0.4 s from the cache, seconds compiling)."""
    n = 17
    P, dx, pending = np.eye(n), np.zeros(n), np.zeros(n)
    predict_covariance(P, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), 0.1, 0.0, 0.0, 0.0, dx)
    fuse_column(P, 0, 1.0, 0.0, 1.0, False, dx, pending)
    fuse_row(P, np.ones(n), 1.0, 0.0, 1.0, False, dx, pending)
    fuse_block(P, 0, np.zeros(2), np.eye(2), 1.0, False, dx, pending)
    fuse_block(P, 0, np.zeros(3), np.eye(3), 1.0, False, dx, pending)
