"""The one fusion routine every aiding source uses: innovation, test ratio, gated update.

Test ratio as in EKF2: ``innovation' S^-1 innovation / gate^2`` with the gate in standard
deviations; above 1 the measurement is rejected and the state is left untouched.

The maths is one compiled call each (:mod:`air_sitl.nav.kernels`): :func:`fuse_direct` for a
measurement of contiguous error states (GNSS and aid position and velocity: H is a selection,
S a sub-block of P); the nonlinear models (compass, airspeed, sideslip, barometric height) are
compiled with their update, their outcome read by :func:`result`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_sitl.nav.ekf import ErrorStateEkf

NO_MODEL = -1  # a compiled model's outcome when the measurement is undefined at the state


@dataclass(frozen=True, slots=True)
class FusionResult:
    """Outcome of one (possibly vector) measurement update."""

    fused: bool
    test_ratio: float  # inf when the innovation covariance was unusable


def result(ekf: ErrorStateEkf, outcome: tuple[float, bool | int]) -> FusionResult:
    """The outcome of a compiled update (which has injected its correction when it fused)."""
    ratio, code = outcome
    fused = code == 1  # True, or a model's 1 (0 rejected; NO_MODEL is the caller's to handle)
    if fused:
        ekf.corrected = True
    return FusionResult(fused, ratio)


def fuse_direct(
    ekf: ErrorStateEkf,
    first: int,
    innovation: list[float],
    R: list[list[float]],
    gate: float,
    *,
    force: bool = False,
) -> FusionResult:
    """Fuse a direct measurement of error states ``first .. first + m - 1`` (m = 1, 2, 3).

    ``force`` skips the gate (resets, tests).
    """
    k = ekf.kernels
    if len(innovation) == 1:  # the common scalar case (height): no arrays to make
        outcome = k.fuse_column(
            ekf.P, ekf.x, first, R[0][0], innovation[0], gate, force, ekf.dx, ekf.pending
        )
    else:
        y, r = np.array(innovation), np.array(R)
        outcome = k.fuse_block(ekf.P, ekf.x, first, y, r, gate, force, ekf.dx, ekf.pending)
    return result(ekf, outcome)
