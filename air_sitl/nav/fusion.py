"""The outcome of a measurement update, as every aiding source reads it.

Test ratio as in EKF2: ``innovation' S^-1 innovation / gate^2`` with the gate in standard
deviations; above 1 the measurement is rejected and the state is left untouched. Each
source's model and update is one compiled call (:mod:`air_sitl.nav.kernels`: position,
velocity, barometric height, compass heading, true airspeed, synthetic sideslip); its
``(ratio, fused)`` becomes a :class:`FusionResult` here.
"""

from __future__ import annotations

from dataclasses import dataclass

from air_sitl.nav.ekf import ErrorStateEkf
from air_sitl.state import positional_builder

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
    return _fusion_result(fused, ratio)


# Built at every measurement update (about 60 a second), positionally (fields in order).
_fusion_result = positional_builder(FusionResult)
