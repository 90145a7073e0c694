"""The one fusion routine every aiding source uses: innovation, test ratio, gated update.

Test ratio as in EKF2: ``innovation' S^-1 innovation / gate^2`` with the gate in standard
deviations; above 1 the measurement is rejected and the state is left untouched.

Two entry points sharing the same maths, shaped for CPython speed (numpy calls on 17x17 cost
about a microsecond each, so the count of calls is what matters): :func:`fuse_direct` for a
measurement of contiguous error states (position, velocity, height: H is a selection, S a
sub-block of P) and :func:`fuse_scalar` for one nonlinear scalar with a dense Jacobian row.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from air_sitl.nav.ekf import ErrorStateEkf, Matrix


@dataclass(frozen=True, slots=True)
class FusionResult:
    """Outcome of one (possibly vector) measurement update."""

    fused: bool
    test_ratio: float  # inf when the innovation covariance was unusable


REJECTED_BAD = FusionResult(False, math.inf)
# np.outer's own ufunc, without np.outer's Python wrapper (same products, bit for bit).
_outer = np.multiply.outer


def _inverse(s: list[list[float]]) -> list[list[float]] | None:
    """Closed-form inverse of a symmetric 1x1, 2x2 or 3x3 matrix; None if not positive."""
    m = len(s)
    if m == 1:
        a = s[0][0]
        return [[1.0 / a]] if a > 0.0 else None
    if m == 2:
        a, b, d = s[0][0], s[0][1], s[1][1]
        det = a * d - b * b
        if not (a > 0.0 and det > 0.0):
            return None
        return [[d / det, -b / det], [-b / det, a / det]]
    (a, b, c), (_, e, f), (_, _, i) = s
    c00 = e * i - f * f
    c01 = c * f - b * i
    c02 = b * f - c * e
    det = a * c00 + b * c01 + c * c02
    if not (a > 0.0 and det > 0.0):
        return None
    c11 = a * i - c * c
    c12 = b * c - a * f
    c22 = a * e - b * b
    r = 1.0 / det
    return [
        [c00 * r, c01 * r, c02 * r],
        [c01 * r, c11 * r, c12 * r],
        [c02 * r, c12 * r, c22 * r],
    ]


def fuse_direct(
    ekf: ErrorStateEkf,
    first: int,
    innovation: list[float],
    R: list[list[float]],
    gate: float,
    *,
    force: bool = False,
) -> FusionResult:
    """Fuse a direct measurement of error states ``first .. first + m - 1``.

    ``force`` skips the gate (resets, tests).
    """
    m = len(innovation)
    P = ekf.P
    if m == 1:  # the common scalar case (height) in fewer numpy calls
        col = P[:, first]  # a view: the outer product below is made before P changes
        s0 = float(col[first]) + R[0][0]
        if not (s0 > 0.0 and math.isfinite(s0)):
            return REJECTED_BAD
        return _gated_scalar(ekf, col, s0, innovation[0], gate, force)
    pht = P[:, first : first + m]
    block = pht[first : first + m].tolist()
    s = [[block[r][c] + R[r][c] for c in range(m)] for r in range(m)]
    s_inv = _inverse(s)
    if s_inv is None:
        return REJECTED_BAD
    y = innovation
    w = [sum(s_inv[r][c] * y[c] for c in range(m)) for r in range(m)]  # S^-1 y
    d2 = sum(y[r] * w[r] for r in range(m))
    if not (d2 >= 0.0 and math.isfinite(d2)):
        return REJECTED_BAD
    ratio = d2 / (gate * gate)
    if ratio > 1.0 and not force:
        return FusionResult(False, ratio)
    dx = pht.dot(w)  # before P changes: pht is a view of it
    P -= pht.dot(s_inv).dot(pht.T)
    ekf.correct(dx)
    return FusionResult(True, ratio)


def fuse_scalar(
    ekf: ErrorStateEkf,
    h: list[float],
    innovation: float,
    R: float,
    gate: float,
    *,
    force: bool = False,
) -> FusionResult:
    """Fuse one scalar measurement with Jacobian row ``h`` (all error states)."""
    P = ekf.P
    hv = np.array(h)
    pht = P.dot(hv)  # .dot: the same BLAS call as @ with less dispatch
    s = float(hv.dot(pht)) + R
    if not (s > 0.0 and math.isfinite(s)):
        return REJECTED_BAD
    return _gated_scalar(ekf, pht, s, innovation, gate, force)


def _gated_scalar(
    ekf: ErrorStateEkf, pht: Matrix, s: float, innovation: float, gate: float, force: bool
) -> FusionResult:
    """The gate and the update of one scalar measurement: ``pht`` = P h', ``s`` = h P h' + R
    (``pht`` may be a view of P: the update is made from it before P changes)."""
    ratio = innovation * innovation / (s * gate * gate)
    if ratio > 1.0 and not force:
        return FusionResult(False, ratio)
    k = pht * (1.0 / s)
    ekf.P -= _outer(k, pht)
    ekf.correct(k * innovation)
    return FusionResult(True, ratio)
