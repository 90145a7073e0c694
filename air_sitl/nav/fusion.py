"""The one fusion routine every aiding source uses: innovation, test ratio, gated update.

Test ratio as in EKF2: ``innovation' S^-1 innovation / gate^2`` with the gate in standard
deviations; above 1 the measurement is rejected and the state is left untouched.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from air_sitl.nav.ekf import ErrorStateEkf


@dataclass(frozen=True, slots=True)
class FusionResult:
    """Outcome of one (possibly vector) measurement update."""

    fused: bool
    test_ratio: float  # inf when the innovation variance was unusable


REJECTED_BAD = FusionResult(False, math.inf)


def fuse(
    ekf: ErrorStateEkf,
    idx: tuple[int, ...],
    innovation: list[float],
    R: list[list[float]],
    gate: float,
    h: list[list[float]] | None = None,
    *,
    force: bool = False,
) -> FusionResult:
    """Fuse an m-dimensional measurement whose Jacobian touches the error states ``idx``.

    ``h`` (m rows of len(idx)) is the Jacobian on those states; None means a direct
    measurement of them (m == len(idx), H a selection: position, velocity, height).
    ``force`` skips the gate (resets, tests).
    """
    P = ekf.P
    cols = P[:, idx]
    if h is None:
        pht = cols
        s = cols[idx, :] + np.array(R)
    else:
        hm = np.array(h)
        pht = cols @ hm.T
        s = hm @ pht[idx, :] + np.array(R)
    m = len(innovation)
    if m == 1:
        s00 = float(s[0, 0])
        if not s00 > 0.0 or not math.isfinite(s00):
            return REJECTED_BAD
        y0 = innovation[0]
        ratio = y0 * y0 / (s00 * gate * gate)
        if ratio > 1.0 and not force:
            return FusionResult(False, ratio)
        k = pht[:, 0] / s00
        P -= np.outer(k, pht[:, 0])
        dx = (k * y0).tolist()
    else:
        try:
            s_inv = np.linalg.inv(s)
        except np.linalg.LinAlgError:
            return REJECTED_BAD
        y = np.array(innovation)
        d2 = float(y @ s_inv @ y)
        if not d2 >= 0.0 or not math.isfinite(d2):
            return REJECTED_BAD
        ratio = d2 / (gate * gate)
        if ratio > 1.0 and not force:
            return FusionResult(False, ratio)
        k_mat = pht @ s_inv
        P -= k_mat @ pht.T
        dx = (k_mat @ y).tolist()
    ekf.correct(dx)
    return FusionResult(True, ratio)
