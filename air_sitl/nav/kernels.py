"""Compiled numerics of the error-state EKF: covariance prediction and measurement updates.

Each is one call where numpy needed five to ten (a numpy call on a 17x17 array costs about
a microsecond, and its machinery crowds the caches the rest of the step runs from). P is
updated in place; a measurement update also writes its correction into ``dx``, adds it to
``pending`` (what the output predictor has not taken yet) and injects it into the nominal
state ``x`` (layout in :mod:`air_sitl.nav.strapdown`), and returns its test ratio and
whether it was fused: ``(inf, False)`` when the innovation covariance is unusable, ``(ratio,
False)`` when the gate rejects it (``force`` skips the gate). The measurement models of the
compass and the airspeed sensor (heading, true airspeed, synthetic sideslip) are compiled
with their update (:func:`fuse_model`): ``(ratio, NO_MODEL)`` when the model is undefined at
the state.

Sums run in index order; no fastmath, so every run gives the same bits.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled
from air_sitl.nav.baro import CURVATURE_1_M
from air_sitl.nav.fusion import NO_MODEL
from air_sitl.nav.quaternion import rotate_global, rotation, wrap_pi

Matrix = npt.NDArray[np.float64]
Vector = npt.NDArray[np.float64]
HEADING, AIRSPEED, SIDESLIP = 0, 1, 2  # the compiled measurement models (fuse_model)
# The exported kernels' signatures (numba's notation, air_sitl.compiled): f8 float64, i8
# int64, b1 bool, f8[::1] a vector, f8[:, ::1] a matrix (both contiguous, as the filter's),
# f8[:] and f8[:, :] any. An update takes P and x, its own arguments, then dx and pending.
_UPDATE = "Tuple((f8, b1))(f8[:, ::1], f8[::1], {}, f8[::1], f8[::1])"
_MODEL = "Tuple((b1, f8, f8[::1]))(f8[::1])"


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


@compiled("void(f8[:, ::1], UniTuple(f8, 9), f8, f8, f8, f8, f8[::1])")
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


@compiled("void(f8[::1], f8[::1])")
def inject(x: Vector, dx: Vector) -> None:
    """Add an error-state correction to the nominal state (attitude: exp(dtheta) * q)."""
    for i in range(6):  # position, velocity
        x[i] += dx[i]
    rotate_global(x, 6, dx[6], dx[7], dx[8])
    for i in range(8):  # gyro bias, accel bias, wind
        x[10 + i] += dx[9 + i]


@compiled
def _update(
    P: Matrix, x: Vector, pht: Matrix, s: float, innovation: float, gate: float, force: bool,
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
    inject(x, dx)
    return ratio, True


@compiled(_UPDATE.format("i8, f8, f8, f8, b1"))
def fuse_column(
    P: Matrix, x: Vector, first: int, R: float, innovation: float, gate: float, force: bool,
    dx: Matrix, pending: Matrix,
) -> tuple[float, bool]:  # fmt: skip
    """One scalar measurement of the error state ``first`` (H selects it)."""
    pht = P[:, first].copy()
    return _update(P, x, pht, pht[first] + R, innovation, gate, force, dx, pending)  # type: ignore[no-any-return]


@compiled(_UPDATE.format("f8[::1], f8, f8, f8, b1"))
def fuse_row(
    P: Matrix, x: Vector, h: Matrix, R: float, innovation: float, gate: float, force: bool,
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
    return _update(P, x, pht, s, innovation, gate, force, dx, pending)  # type: ignore[no-any-return]


@compiled(_UPDATE.format("i8, f8[:], f8[:, :], f8, b1"))
def fuse_block(
    P: Matrix, x: Vector, first: int, y: Matrix, R: Matrix, gate: float, force: bool,
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
    inject(x, dx)
    return ratio, True


@compiled(_UPDATE.format("f8, f8, f8, f8"))
def fuse_height(
    P: Matrix, x: Vector, height_m: float, lag_s: float, R: float, gate: float, dx: Vector,
    pending: Vector,
) -> tuple[float, bool]:  # fmt: skip
    """A barometric height above home taken ``lag_s`` before the state's time: the down
    position in the tangent plane at home, the Earth's curvature added, against the
    predicted down position then."""
    down = -height_m + (x[0] * x[0] + x[1] * x[1]) * CURVATURE_1_M
    y = down - (x[2] - x[5] * lag_s)
    return fuse_column(P, x, 2, R, y, gate, False, dx, pending)  # type: ignore[no-any-return]


@compiled(_UPDATE.format("f8, f8, f8, f8, f8, f8, f8"))
def fuse_position(
    P: Matrix, x: Vector, north: float, east: float, lag_s: float, vnn: float, vne: float,
    vee: float, gate: float, dx: Vector, pending: Vector,
) -> tuple[float, bool]:  # fmt: skip
    """A horizontal position (GNSS, an external aid) taken ``lag_s`` before the state's time,
    its covariance (vnn, vne, vee), against the predicted position then."""
    y = np.empty(2)
    y[0] = north - (x[0] - x[3] * lag_s)
    y[1] = east - (x[1] - x[4] * lag_s)
    R = np.empty((2, 2))
    R[0, 0], R[0, 1], R[1, 0], R[1, 1] = vnn, vne, vne, vee
    return fuse_block(P, x, 0, y, R, gate, False, dx, pending)  # type: ignore[no-any-return]


@compiled(_UPDATE.format("f8, f8, f8, f8, f8"))
def fuse_velocity(
    P: Matrix, x: Vector, vn: float, ve: float, vd: float, var: float, gate: float, dx: Vector,
    pending: Vector,
) -> tuple[float, bool]:  # fmt: skip
    """A 3-D velocity (GNSS), each component of variance ``var``."""
    y = np.empty(3)
    y[0], y[1], y[2] = vn - x[3], ve - x[4], vd - x[5]
    R = np.zeros((3, 3))
    R[0, 0], R[1, 1], R[2, 2] = var, var, var
    return fuse_block(P, x, 3, y, R, gate, False, dx, pending)  # type: ignore[no-any-return]


@compiled(_MODEL)
def heading_model(x: Vector) -> tuple[bool, float, Vector]:
    """(defined, yaw (ZYX) of the attitude, its Jacobian on the error state): undefined when
    the body x axis is vertical."""
    h = np.zeros(17)
    r = rotation(x[6], x[7], x[8], x[9])
    r00, r10, r20 = r[0], r[3], r[6]
    d = r00 * r00 + r10 * r10
    if d < 1e-6:
        return False, 0.0, h
    h[6] = -r00 * r20 / d
    h[7] = -r10 * r20 / d
    h[8] = 1.0
    return True, math.atan2(r10, r00), h


@compiled(_MODEL)
def airspeed_model(x: Vector) -> tuple[bool, float, Vector]:
    """(defined, true airspeed |v - wind| with the wind horizontal, its Jacobian): undefined
    below 1 m/s of air (no direction to measure along)."""
    h = np.zeros(17)
    vn, ve, vd = x[3], x[4], x[5]
    rn, re = vn - x[16], ve - x[17]
    pred = math.sqrt(rn * rn + re * re + vd * vd)
    if pred < 1.0:
        return False, pred, h
    inv = 1.0 / pred
    h[3], h[4], h[5] = rn * inv, re * inv, vd * inv
    h[15], h[16] = -rn * inv, -re * inv
    return True, pred, h


@compiled(_MODEL)
def sideslip_model(x: Vector) -> tuple[bool, float, Vector]:
    """(defined, sideslip = body y / body x air velocity, its Jacobian): undefined when the
    air does not come from ahead (below 1 m/s along the body x axis)."""
    h = np.zeros(17)
    r = rotation(x[6], x[7], x[8], x[9])
    a0, a1, a2 = x[3] - x[16], x[4] - x[17], x[5]
    # Body air velocity = R^T a; column i of R is body axis i in NED.
    c0 = (r[0], r[3], r[6])
    c1 = (r[1], r[4], r[7])
    bx = c0[0] * a0 + c0[1] * a1 + c0[2] * a2
    by = c1[0] * a0 + c1[1] * a1 + c1[2] * a2
    if bx < 1.0:
        return False, 0.0, h
    beta = by / bx
    # d(body_i)/d(dtheta) = c_i x a (global attitude error); d/dv = c_i; d/dwind = -c_i;
    # d(beta) = d(by) / bx - by d(bx) / bx^2.
    x0 = (c0[1] * a2 - c0[2] * a1, c0[2] * a0 - c0[0] * a2, c0[0] * a1 - c0[1] * a0)
    x1 = (c1[1] * a2 - c1[2] * a1, c1[2] * a0 - c1[0] * a2, c1[0] * a1 - c1[1] * a0)
    inv = 1.0 / bx
    k = by * inv * inv
    for i in range(3):
        h[3 + i] = c1[i] * inv - c0[i] * k
        h[6 + i] = x1[i] * inv - x0[i] * k
    h[15], h[16] = -h[3], -h[4]
    return True, beta, h


@compiled("Tuple((f8, i8))(f8[:, ::1], f8[::1], i8, f8, f8, f8, f8[::1], f8[::1])")
def fuse_model(
    P: Matrix, x: Vector, model: int, measured: float, R: float, gate: float, dx: Vector,
    pending: Vector,
) -> tuple[float, int]:  # fmt: skip
    """One reading of a compiled model: HEADING (a compass heading plus declination, the
    innovation wrapped to [-pi, pi]), AIRSPEED (true airspeed) or SIDESLIP (zero, synthetic:
    ``measured`` unused)."""
    if model == HEADING:
        defined, value, h = heading_model(x)
    elif model == AIRSPEED:
        defined, value, h = airspeed_model(x)
    else:
        defined, value, h = sideslip_model(x)
    if not defined:
        return 0.0, NO_MODEL
    if model == HEADING:
        y = wrap_pi(measured - value)
    elif model == AIRSPEED:
        y = measured - value
    else:
        y = -value
    ratio, fused = fuse_row(P, x, h, R, y, gate, False, dx, pending)
    return ratio, int(fused)


@functools.cache
def warm() -> None:
    """Run every kernel once: where numba's JIT compiles them (``air_sitl.compiled``) this
    compiles them now or loads them from numba's disk cache (0.4 s from the cache, seconds
    compiling); a flight's filter calls it when it is built, before the clock runs, so the
    first measurement update does not stall the simulation thread mid-flight. Built
    kernels are ready: microseconds."""
    n = 17
    P, dx, pending = np.eye(n), np.zeros(n), np.zeros(n)
    x = np.zeros(18)
    x[3], x[6] = 20.0, 1.0
    predict_covariance(P, (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0), 0.1, 0.0, 0.0, 0.0, dx)
    fuse_column(P, x, 0, 1.0, 0.0, 1.0, False, dx, pending)
    fuse_row(P, x, np.ones(n), 1.0, 0.0, 1.0, False, dx, pending)
    fuse_block(P, x, 0, np.zeros(2), np.eye(2), 1.0, False, dx, pending)
    fuse_block(P, x, 0, np.zeros(3), np.eye(3), 1.0, False, dx, pending)
    fuse_height(P, x, 100.0, 0.1, 1.0, 1.0, dx, pending)
    fuse_position(P, x, 1.0, 1.0, 0.1, 1.0, 0.0, 1.0, 1.0, dx, pending)
    fuse_velocity(P, x, 20.0, 0.0, 0.0, 1.0, 1.0, dx, pending)
    for model in (HEADING, AIRSPEED, SIDESLIP):
        fuse_model(P, x, model, 0.0, 1.0, 1.0, dx, pending)
    inject(x, dx)
