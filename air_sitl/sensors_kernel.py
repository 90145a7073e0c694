"""The IMU and AHRS of :class:`air_sitl.sensors.SensorSuite` compiled (:mod:`air_sitl.compiled`,
group ``flight``): one call per physics step, operation for operation as the Python was (the
same bytes).

The suite's noise figures come in a float64 array (indices below), its slowly varying errors
(gyro and accelerometer biases, the AHRS drift) in another that :func:`imu` updates in place,
the step's standard normal draws as a row of a pre-drawn block.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from air_sitl.compiled import compiled

Array = npt.NDArray[np.float64]

# The figures: bias walk and AHRS drift per step, white noise of gyro, accelerometer and
# AHRS, the drift's bound.
WALK, GYRO_NOISE, ACCEL_NOISE, DRIFT, AHRS_NOISE, DRIFT_LIMIT = range(6)


@compiled(
    "Tuple((UniTuple(f8, 3), UniTuple(f8, 3), UniTuple(f8, 4)))"
    "(f8[:, ::1], i8, f8[::1], f8[::1], UniTuple(f8, 3), UniTuple(f8, 3), UniTuple(f8, 4))"
)
def imu(
    Z: Array, row: int, E: Array, F: Array, rates: tuple[float, float, float],
    force: tuple[float, float, float], attitude: tuple[float, float, float, float],
) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:  # fmt: skip
    """Gyro (3), accelerometer (3) and the AHRS quaternion (4), as ImuSample's tuples, of the
    truth's ``rates`` (p, q, r), specific ``force`` and ``attitude`` (w, x, y, z: the
    VehicleState's tuples as they are), with the draws ``Z[row]``: per step bias walk (3),
    gyro noise (3), accel noise (3), AHRS drift (3), jitter (3). ``E``: gyro bias (3),
    accelerometer bias (3), AHRS drift (3), updated."""
    p, q, r = rates
    fx, fy, fz = force
    aw, ax, ay, az = attitude
    z = Z[row]
    walk = F[WALK]
    E[0] += z[0] * walk
    E[1] += z[1] * walk
    E[2] += z[2] * walk
    gs = F[GYRO_NOISE]
    acs = F[ACCEL_NOISE]
    g0 = p + E[0] + z[3] * gs
    g1 = q + E[1] + z[4] * gs
    g2 = r + E[2] + z[5] * gs
    a0 = fx + E[3] + z[6] * acs
    a1 = fy + E[4] + z[7] * acs
    a2 = fz + E[5] + z[8] * acs
    # AHRS: truth rotated by a small error (bounded random-walk drift + white jitter):
    # frames.quat_multiply and frames.quat_normalize written out.
    lim = F[DRIFT_LIMIT]
    neg = -lim
    ds = F[DRIFT]
    for j in range(3):
        v = E[6 + j] + z[9 + j] * ds
        v = v if v < lim else lim
        E[6 + j] = v if v > neg else neg
    js = F[AHRS_NOISE]
    ex = (E[6] + z[12] * js) * 0.5
    ey = (E[7] + z[13] * js) * 0.5
    ez = (E[8] + z[14] * js) * 0.5
    qw = aw - ax * ex - ay * ey - az * ez  # the error's scalar part is 1
    qx = aw * ex + ax + ay * ez - az * ey
    qy = aw * ey - ax * ez + ay + az * ex
    qz = aw * ez + ax * ey - ay * ex + az
    norm = math.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    k = 1.0 / norm if qw >= 0 else -1.0 / norm
    return (g0, g1, g2), (a0, a1, a2), (qw * k, qx * k, qy * k, qz * k)
