"""``fused``: dead reckoning corrected by map-matching fixes in a Kalman filter, with gating.

The strongest baseline. Between frames the filter
(:mod:`air_sitl.localize.mapmatch_filter`) integrates the airspeed along the AHRS heading plus
a learnt velocity offset (wind, airspeed and heading errors); at each frame the map matcher of
``mapmatch`` searches around the filter's prediction (the radius follows its uncertainty), and
a fix that passes the matcher's quality gate is fused only if its innovation passes a
Mahalanobis test (chi-square, 2 degrees of freedom, 99.9 %). Gated-out fixes are not lost
evidence: when :data:`REACQUIRE_FIXES` consecutive ones agree with each other (the filter has
drifted, not the matcher), the filter restarts at the latest. The output is the filter's
state at every frame, its covariance, and a quality from its uncertainty.
"""

from __future__ import annotations

import math
from typing import Any

from air_sitl.localize.base import Estimate, Observation
from air_sitl.localize.mapmatch import MapMatchBase
from air_sitl.localize.mapmatch_filter import CHI2_2DOF_999

REACQUIRE_FIXES = 15  # consecutive gated-out fixes that agree -> restart at the latest
REACQUIRE_SPREAD_M = 5.0  # "agree": their innovations lie within this of their mean
QUALITY_SIGMA_M = 25.0  # quality 0 at this 1-sigma (the recall threshold)


class FusedLocalizer(MapMatchBase):
    """Dead reckoning + gated map-matching fixes."""

    name = "fused"

    def __init__(self, *, gate_d2: float = CHI2_2DOF_999, **options: Any) -> None:
        super().__init__(**options)
        self.gate_d2 = gate_d2
        self._rejected: list[tuple[float, float, float, float]] = []  # innovations, fix
        self.fixes_fused = 0
        self.fixes_gated = 0
        self.restarts = 0

    def _clear(self) -> None:
        super()._clear()
        self._rejected = []
        self.fixes_fused = self.fixes_gated = self.restarts = 0

    def fuse_fix(self, east_m: float, north_m: float, sigma_m: float) -> bool:
        """Offer one absolute fix to the filter; False when the innovation gate refuses it.

        A refused fix is remembered: :data:`REACQUIRE_FIXES` consecutive refused fixes whose
        innovations agree restart the filter at the last of them.
        """
        if self.filter.update(east_m, north_m, sigma_m, gate_d2=self.gate_d2):
            self.fixes_fused += 1
            self.refusals = 0
            self._rejected.clear()
            return True
        self.fixes_gated += 1
        self.refusals += 1  # the search widens, so that a lost filter finds the fixes again
        pe, pn = self.filter.position
        self._rejected.append((east_m - pe, north_m - pn, east_m, north_m))
        if len(self._rejected) >= REACQUIRE_FIXES:
            recent = self._rejected[-REACQUIRE_FIXES:]
            me = sum(r[0] for r in recent) / len(recent)
            mn = sum(r[1] for r in recent) / len(recent)
            if all(math.hypot(r[0] - me, r[1] - mn) <= REACQUIRE_SPREAD_M for r in recent):
                self.filter.start(east_m, north_m, sigma_m)
                self.restarts += 1
                self.refusals = 0
                self._rejected.clear()
        return False

    def step(self, obs: Observation) -> Estimate | None:
        """Predict, match around the prediction, gate and fuse; the filter's state."""
        self._inputs(obs)
        result = self._match(obs)
        if result is not None and result.accepted:
            self.fuse_fix(result.east_m, result.north_m, result.sigma_m)
        quality = max(0.0, min(1.0, 1.0 - self.filter.sigma_m / QUALITY_SIGMA_M))
        return self._propagated(obs, quality=quality)
