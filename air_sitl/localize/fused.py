"""``fused``: dead reckoning corrected by map-matching fixes in a Kalman filter, with gating.

The strongest baseline. Between frames the filter
(:mod:`air_sitl.localize.mapmatch_filter`) integrates the airspeed along the AHRS heading plus
a learnt velocity offset (wind, airspeed and heading errors); it also learns the AHRS tilt
error, which moves every map fix by about height x tilt along the body axes (the bias that
sets ``mapmatch``'s median: turns make it observable). At each frame the map matcher of
``mapmatch`` searches around the filter's prediction (the radius follows its uncertainty), and
a fix that passes the matcher's quality gate is fused only if its innovation passes a
Mahalanobis test (chi-square, 2 degrees of freedom, 99.9 %). Gated-out fixes are not lost
evidence: when :data:`REACQUIRE_FIXES` consecutive ones agree with each other (the filter has
drifted, not the matcher), the filter restarts at the latest. The output is the filter's
state at every frame, its covariance, and a quality from its uncertainty; ``fix`` is True at a
frame whose map fix corrected the filter (fused, or restarting it).
"""

from __future__ import annotations

import math
from typing import Any

from air_sitl.localize.base import Estimate, Observation
from air_sitl.localize.mapmatch import MapMatchBase
from air_sitl.localize.mapmatch_filter import CHI2_2DOF_999, heading_rad

REACQUIRE_FIXES = 15  # consecutive gated-out fixes that agree -> restart at the latest
REACQUIRE_SPREAD_M = 5.0  # "agree": their innovations lie within this of their mean
QUALITY_SIGMA_M = 25.0  # quality 0 at this 1-sigma (the recall threshold)


class FusedLocalizer(MapMatchBase):
    """Dead reckoning + gated map-matching fixes."""

    name = "fused"
    tilt_states = True

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

    def _where(self) -> dict[str, float | None]:
        """Height and AHRS heading of the current frame: what relates a fix to the tilt."""
        heading = heading_rad(self.prev_q) if self.prev_q is not None else None
        return {"height_m": self.height_m, "heading": heading}

    def expected_fix(self) -> tuple[float, float]:
        """Where a map fix of the current frame should fall (the position plus the tilt's
        offset)."""
        return self.filter.expected_fix(**self._where())

    def fuse_fix(self, east_m: float, north_m: float, sigma_m: float) -> bool:
        """Offer one map fix of the current frame to the filter; False when the innovation gate
        refuses it.

        A refused fix is remembered: :data:`REACQUIRE_FIXES` consecutive refused fixes whose
        innovations agree restart the filter at the last of them (less the tilt's offset).
        """
        where = self._where()
        if self.filter.update(east_m, north_m, sigma_m, gate_d2=self.gate_d2, **where):
            self.fixes_fused += 1
            self.refusals = 0
            self._rejected.clear()
            return True
        self.fixes_gated += 1
        self.refusals += 1  # the search widens, so that a lost filter finds the fixes again
        pe, pn = self.filter.expected_fix(**where)
        self._rejected.append((east_m - pe, north_m - pn, east_m, north_m))
        if len(self._rejected) >= REACQUIRE_FIXES:
            recent = self._rejected[-REACQUIRE_FIXES:]
            me = sum(r[0] for r in recent) / len(recent)
            mn = sum(r[1] for r in recent) / len(recent)
            if all(math.hypot(r[0] - me, r[1] - mn) <= REACQUIRE_SPREAD_M for r in recent):
                # Where this fix puts the aircraft: the fix less the tilt's offset.
                east, north = self.filter.position
                self.filter.start(east + east_m - pe, north + north_m - pn, sigma_m)
                self.restarts += 1
                self.refusals = 0
                self._rejected.clear()
        return False

    def step(self, obs: Observation) -> Estimate | None:
        """Predict, match around the prediction, gate and fuse; the filter's state."""
        self._inputs(obs)
        result = self._match(obs)
        fixed = False  # the fix corrected the filter: fused, or restarted it
        if result is not None and result.accepted:
            restarts = self.restarts
            fixed = self.fuse_fix(result.east_m, result.north_m, result.sigma_m)
            fixed = fixed or self.restarts > restarts
        quality = max(0.0, min(1.0, 1.0 - self.filter.sigma_m / QUALITY_SIGMA_M))
        return self._propagated(obs, quality=quality, fix=fixed)
