"""Compiled strapdown numerics: the delayed filter's prediction and the output predictor.

As in PX4 EKF2 the filter runs ``fusion_horizon`` behind the newest IMU sample, so a
measurement that arrives late (up to the horizon) is fused at the time it refers to, and the
estimate of *now* comes from an output predictor: the same strapdown integration run ahead
over the IMU deltas the delayed filter has not reached yet (kept in a ring). Each correction
of the delayed state is carried forward to the output state to first order (position by the
velocity correction times the window, velocity by the attitude correction crossed with the
specific-force increment of the window); once a second the output is recomputed exactly by
replaying the ring from the delayed state.

One filter period (20 ms) is three calls: :func:`advance` (output predictor and ring),
:func:`delayed_predict` (the delayed state, and its covariance every few periods), then
:func:`carry` or :func:`replay` after the measurement updates. The state lives in float64
arrays, laid out as below; every operation rounds as the Python it replaced, in its order.

- ``x``, the delayed nominal state (``ErrorStateEkf.x``): p 0-2, v 3-5 (NED from home),
  q 6-9 (body->NED, w x y z), gyro bias 10-12, accel bias 13-15 (body FRD), wind 16-17 (N, E).
- ``o``, the output predictor: p 0-2, v 3-5, q 6-9, and the running sums of the NED
  specific-force delta velocity (10-12) and of its integral (13-15).
- the ring of IMU deltas, one row each: raw delta angle 0-2 (rad), raw delta velocity 3-5
  (m/s, body FRD), dt 6, the output's running sums at its end 7-12; ``ri`` (int64): head,
  count, then each row's end time in ns.
- ``consts``: gravity, then the process noise densities per second of a covariance step
  (velocity, angle, gyro bias, accel bias, wind), then the periods per covariance step.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled
from air_sitl.nav.kernels import predict_covariance
from air_sitl.nav.quaternion import rotate_global, rotation, unit_product

Vector = npt.NDArray[np.float64]
Matrix = npt.NDArray[np.float64]
Index = npt.NDArray[np.int64]

NX = 18  # the nominal state
NO = 16  # the output predictor
NE = 20  # the estimate output_estimate writes
RING_COLS = 13
LAST = 6  # the running sums of the last delta the delayed filter took
NEVER = 2**62  # the end time of a delta after the last one: after any simulated time
# The exported kernels' signatures: as in air_sitl.nav.kernels; the ring a matrix, ri a
# vector of int64 (i8[::1]).


@compiled("UniTuple(f8, 3)(f8[::1], f8, f8, f8, f8, f8, f8, f8, f8)")
def integrate(
    s: Vector, dax: float, day: float, daz: float, dvx: float, dvy: float, dvz: float,
    dt: float, g: float,
) -> tuple[float, float, float]:  # fmt: skip
    """One strapdown step of ``s[0:10]`` (p, v, q) with bias-corrected deltas, in place;
    returns the delta velocity in NED without gravity.

    The velocity delta is rotated with the mid-interval attitude (first-order sculling), the
    quaternion advanced with the exact rotation of the delta angle.
    """
    # Rotate dv by the half-step rotation first: dv + 0.5 * dang x dv.
    dx = dvx + 0.5 * (day * dvz - daz * dvy)
    dy = dvy + 0.5 * (daz * dvx - dax * dvz)
    dz = dvz + 0.5 * (dax * dvy - day * dvx)
    w, x, y, z = s[6], s[7], s[8], s[9]
    tx = 2.0 * (y * dz - z * dy)
    ty = 2.0 * (z * dx - x * dz)
    tz = 2.0 * (x * dy - y * dx)
    nx = dx + w * tx + (y * tz - z * ty)
    ny = dy + w * ty + (z * tx - x * tz)
    nz = dz + w * tz + (x * ty - y * tx)
    angle2 = dax * dax + day * day + daz * daz
    if angle2 > 1e-12:
        angle = math.sqrt(angle2)
        f = math.sin(0.5 * angle) / angle
        c = math.cos(0.5 * angle)
    else:
        f = 0.5
        c = 1.0 - angle2 / 8.0
    v0, v1, v2 = s[3], s[4], s[5]
    w0 = v0 + nx
    w1 = v1 + ny
    w2 = v2 + nz + g * dt
    h = 0.5 * dt
    s[0] = s[0] + (v0 + w0) * h
    s[1] = s[1] + (v1 + w1) * h
    s[2] = s[2] + (v2 + w2) * h
    s[3], s[4], s[5] = w0, w1, w2
    # q * exp(dang): a rotation in the body frame.
    s[6], s[7], s[8], s[9] = unit_product(w, x, y, z, c, dax * f, day * f, daz * f)
    return nx, ny, nz


@compiled
def _integrate_unbiased(
    s: Vector, x: Vector, row: Vector, dt: float, g: float
) -> tuple[float, float, float]:
    """:func:`integrate` of a ring row's raw deltas, minus the biases of ``x`` over ``dt``."""
    return integrate(  # type: ignore[no-any-return]
        s,
        row[0] - x[10] * dt,
        row[1] - x[11] * dt,
        row[2] - x[12] * dt,
        row[3] - x[13] * dt,
        row[4] - x[14] * dt,
        row[5] - x[15] * dt,
        dt,
        g,
    )


@compiled("i8(f8[::1], f8[::1], f8[:, ::1], i8[::1], i8, f8, f8, f8, f8, f8, f8, f8, f8)")
def advance(
    o: Vector, x: Vector, ring: Matrix, ri: Index, t_ns: int, a0: float, a1: float, a2: float,
    a3: float, a4: float, a5: float, dt: float, g: float,
) -> int:  # fmt: skip
    """The output predictor over one summed IMU delta (``a``: delta angle, delta velocity; the
    biases of ``x``), and the delta pushed on the ring for the delayed filter; returns the
    end time of the ring's oldest delta."""
    cap = ring.shape[0]
    if ri[1] == cap:  # cannot happen with the ring sized to the horizon: drop the oldest
        ri[0] = (ri[0] + 1) % cap
        ri[1] -= 1
    k = (ri[0] + ri[1]) % cap
    row = ring[k]
    row[0], row[1], row[2], row[3], row[4], row[5], row[6] = a0, a1, a2, a3, a4, a5, dt
    nx, ny, nz = _integrate_unbiased(o, x, row, dt, g)
    cv0, cv1, cv2 = o[10], o[11], o[12]
    o[13] = o[13] + (cv0 + 0.5 * nx) * dt
    o[14] = o[14] + (cv1 + 0.5 * ny) * dt
    o[15] = o[15] + (cv2 + 0.5 * nz) * dt
    o[10], o[11], o[12] = cv0 + nx, cv1 + ny, cv2 + nz
    for i in range(6):
        row[7 + i] = o[10 + i]
    ri[2 + k] = t_ns
    ri[1] += 1
    return ri[2 + ri[0]]  # type: ignore[no-any-return]


@compiled(
    "Tuple((i8, f8, i8))(f8[::1], f8[:, ::1], f8[::1], f8[:, ::1], i8[::1], f8[::1], f8[::1])"
)
def delayed_predict(
    x: Vector, P: Matrix, cov: Vector, ring: Matrix, ri: Index, consts: Vector, last: Vector
) -> tuple[int, float, int]:
    """Take the oldest delta of the ring (there is one) and predict the delayed state over it
    (the covariance every ``consts[6]`` deltas, summed); (its end time, its dt, the end time of
    the next delta or NEVER). ``last`` keeps its output running sums (for :func:`carry`).

    ``cov`` sums the deltas since the last covariance step: dt, NED delta velocity, count.
    """
    cap = ring.shape[0]
    k = ri[0]
    t_ns = ri[2 + k]
    ri[0] = (k + 1) % cap
    ri[1] -= 1
    row = ring[k]
    dt = row[6]
    nx, ny, nz = _integrate_unbiased(x, x, row, dt, consts[0])
    cov[1] += nx
    cov[2] += ny
    cov[3] += nz
    cov[0] += dt
    cov[4] += 1.0
    if cov[4] >= consts[6]:
        covariance_step(x, P, cov, consts)
    for i in range(LAST):
        last[i] = row[7 + i]
    return t_ns, dt, ri[2 + ri[0]] if ri[1] > 0 else NEVER


@compiled("void(f8[::1], f8[:, ::1], f8[::1], f8[::1])")
def covariance_step(x: Vector, P: Matrix, cov: Vector, consts: Vector) -> None:
    """P over the deltas summed in ``cov`` (then emptied), Q from the densities in ``consts``."""
    T = cov[0]
    qv, qa, qbg, qba, qw = consts[1] * T, consts[2] * T, consts[3] * T, consts[4] * T, consts[5] * T
    q_diag = np.array((0.0, 0.0, 0.0, qv, qv, qv, qa, qa, qa, qbg, qbg, qbg, qba, qba, qba, qw, qw))
    r = rotation(x[6], x[7], x[8], x[9])
    predict_covariance(P, r, T, cov[1], cov[2], cov[3], q_diag)
    cov[:] = 0.0


@compiled("void(f8[::1], f8[::1], f8, f8[::1])")
def carry(o: Vector, pending: Vector, window_s: float, last: Vector) -> None:
    """Apply the corrections ``pending`` made to the delayed state ``window_s`` ago to the
    output (first order), then empty ``pending``. ``last`` holds the output's running sums at
    the delayed time: the differences with the current sums are the specific-force delta
    velocity (and position) over the window."""
    nonzero = False
    for i in range(pending.shape[0]):
        if pending[i] != 0.0:
            nonzero = True
    if not nonzero:
        return
    dx = pending
    window_s = max(window_s, 0.0)
    ex, ey, ez = dx[6], dx[7], dx[8]
    # Gyro and accelerometer bias corrections act over the window too.
    bgx, bgy, bgz = dx[9], dx[10], dx[11]
    bax, bay, baz = dx[12], dx[13], dx[14]
    if bgx or bgy or bgz or bax or bay or baz:
        r = rotation(o[6], o[7], o[8], o[9])
        w = window_s
        ex -= (r[0] * bgx + r[1] * bgy + r[2] * bgz) * w
        ey -= (r[3] * bgx + r[4] * bgy + r[5] * bgz) * w
        ez -= (r[6] * bgx + r[7] * bgy + r[8] * bgz) * w
        avx = -(r[0] * bax + r[1] * bay + r[2] * baz) * w
        avy = -(r[3] * bax + r[4] * bay + r[5] * baz) * w
        avz = -(r[6] * bax + r[7] * bay + r[8] * baz) * w
    else:
        avx = avy = avz = 0.0
    sv0, sv1, sv2 = o[10] - last[0], o[11] - last[1], o[12] - last[2]
    sp0 = o[13] - last[3] - last[0] * window_s
    sp1 = o[14] - last[4] - last[1] * window_s
    sp2 = o[15] - last[5] - last[2] * window_s
    ax, ay, az = dx[6], dx[7], dx[8]
    # d(R f) = dtheta x (R f): velocity and position pick up the rotated increments.
    o[3] = o[3] + dx[3] + (ay * sv2 - az * sv1) + avx
    o[4] = o[4] + dx[4] + (az * sv0 - ax * sv2) + avy
    o[5] = o[5] + dx[5] + (ax * sv1 - ay * sv0) + avz
    h = 0.5 * window_s
    o[0] = o[0] + dx[0] + dx[3] * window_s + (ay * sp2 - az * sp1) + avx * h
    o[1] = o[1] + dx[1] + dx[4] * window_s + (az * sp0 - ax * sp2) + avy * h
    o[2] = o[2] + dx[2] + dx[5] * window_s + (ax * sp1 - ay * sp0) + avz * h
    rotate_global(o, 6, ex, ey, ez)
    pending[:] = 0.0


@compiled("void(f8[::1], f8[::1], f8[:, ::1], i8[::1], f8, f8[::1])")
def replay(o: Vector, x: Vector, ring: Matrix, ri: Index, g: float, pending: Vector) -> None:
    """Recompute the output exactly from the delayed state and the ring (the corrections
    pending for the output are in it now: emptied)."""
    for i in range(10):
        o[i] = x[i]
    cap = ring.shape[0]
    for j in range(ri[1]):
        row = ring[(ri[0] + j) % cap]
        _integrate_unbiased(o, x, row, row[6], g)
    pending[:] = 0.0


@compiled("void(f8[::1], f8[::1], f8[:, ::1], f8, f8, f8, f8, f8, f8, f8, f8, f8[::1])")
def output_estimate(
    o: Vector, x: Vector, P: Matrix, a0: float, a1: float, a2: float, a3: float, a4: float,
    a5: float, dt: float, g: float, res: Vector,
) -> None:  # fmt: skip
    """The state at the newest IMU time into ``res``: the output advanced over the IMU sums
    ``a`` of the last ``dt`` s (fewer than one filter period; none when ``dt`` is 0).

    ``res``: p 0-2, v 3-5, q 6-9, horizontal and vertical standard deviations 10-11, wind
    12-13, gyro bias 14-16, accel bias 17-19.
    """
    for i in range(10):
        res[i] = o[i]
    if dt > 0.0:
        integrate(
            res,
            a0 - x[10] * dt,
            a1 - x[11] * dt,
            a2 - x[12] * dt,
            a3 - x[13] * dt,
            a4 - x[14] * dt,
            a5 - x[15] * dt,
            dt,
            g,
        )
    a, b, c = P[0, 0], P[0, 1], P[1, 1]
    big = 0.5 * (a + c) + math.sqrt(max(0.0, 0.25 * (a - c) ** 2 + b * b))
    res[10] = math.sqrt(max(big, 0.0))
    res[11] = math.sqrt(max(P[2, 2], 0.0))
    res[12], res[13] = x[16], x[17]
    for i in range(6):
        res[14 + i] = x[10 + i]


@functools.cache
def warm() -> None:
    """Run every kernel once (compiled now where numba's JIT compiles them): see
    :func:`air_sitl.nav.kernels.warm`."""
    x, o, P = np.zeros(NX), np.zeros(NO), np.eye(17)
    x[6] = o[6] = 1.0
    ring, ri = np.zeros((4, RING_COLS)), np.zeros(6, dtype=np.int64)
    consts, cov, last = np.ones(7), np.zeros(5), np.zeros(LAST)
    advance(o, x, ring, ri, 1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.02, 9.8)
    delayed_predict(x, P, cov, ring, ri, consts, last)
    carry(o, np.ones(17) * 1e-9, 0.1, last)
    replay(o, x, ring, ri, 9.8, np.zeros(17))
    output_estimate(o, x, P, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.01, 9.8, np.zeros(NE))
