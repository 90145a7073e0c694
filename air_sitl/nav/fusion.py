"""The one fusion routine every aiding source uses: innovation, test ratio, gated update.

Test ratio as in EKF2: ``innovation' S^-1 innovation / gate^2`` with the gate in standard
deviations; above 1 the measurement is rejected and the state is left untouched.

Two entry points, shaped for CPython speed (the maths is one compiled call each: see
:mod:`air_sitl.nav.kernels`): :func:`fuse_direct` for a measurement of contiguous error states
(position, velocity, height: H is a selection, S a sub-block of P) and :func:`fuse_scalar`
for one nonlinear scalar with a dense Jacobian row.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from air_sitl.nav.ekf import ErrorStateEkf


@dataclass(frozen=True, slots=True)
class FusionResult:
    """Outcome of one (possibly vector) measurement update."""

    fused: bool
    test_ratio: float  # inf when the innovation covariance was unusable


def _result(ekf: ErrorStateEkf, outcome: tuple[float, bool]) -> FusionResult:
    ratio, fused = outcome
    if fused:
        ekf.inject(ekf.dx.tolist())
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
            ekf.P, first, R[0][0], innovation[0], gate, force, ekf.dx, ekf.pending
        )
    else:
        outcome = k.fuse_block(
            ekf.P, first, np.array(innovation), np.array(R), gate, force, ekf.dx, ekf.pending
        )
    return _result(ekf, outcome)


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
    outcome = ekf.kernels.fuse_row(
        ekf.P, np.array(h), R, innovation, gate, force, ekf.dx, ekf.pending
    )
    return _result(ekf, outcome)
