"""``mapmatch``: absolute position from each frame against an orthophoto of another date.

Per frame: rectify the frame with the AHRS attitude and the barometric height onto the
reference map's pixel grid around the prior, locate it by orientation correlation
(:mod:`air_sitl.localize.mapmatch_core`), refuse weak matches (peak ratio, response, overlap,
peak on the search border). The prior is the last position moved on by dead reckoning
(airspeed along the AHRS heading plus a velocity offset learnt from the fixes,
:mod:`air_sitl.localize.mapmatch_filter`), and the search radius follows its uncertainty.

Output, every frame: an accepted match gives the fix itself (covariance from the attitude
floor and the peak ratio, quality >= 0.5, ``fix`` True); a refused or skipped frame gives the
propagated position with its grown covariance, a quality below 0.5 (0 when refused) and
``fix`` False, so that availability stays at 100 % after the first frame, recall counts what
the method really holds and the fix rate what the map gave. ``every=k`` matches every k-th
frame only (propagating between).

Reference: ``reference_map`` (``urban``, ``forest`` or GeoTIFF path(s), as ``--map``) at
``reference_date`` (default 0) from the driver's context; without one, the flight's own
map (manifest ``map``: a procedural one, or the GeoTIFF dates its ``spec`` names) at date 0,
or date 1 when the flight itself is at date 0: always another date than the imagery unless
asked otherwise. A driver may open the reference itself (``LocalizerContext.extras``
:data:`OPEN_MAP_EXTRA`: a function with :func:`air_sitl.maps.open_map`'s signature): a sweep's
worker keeps it from run to run and shares its drawn ground with the other workers, the same
pixels as opening it here.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from air_sitl.errors import OptionError
from air_sitl.localize.base import Estimate, LocalizerContext, Observation
from air_sitl.localize.decode import decode_gray
from air_sitl.localize.inputs import fix_position_ned
from air_sitl.localize.mapmatch_core import MapMatcher, MatchResult
from air_sitl.localize.mapmatch_filter import (
    POSITION_NOISE_M2_S,
    PositionFilter,
    air_velocity_en,
)
from air_sitl.maps import open_map
from air_sitl.maps.base import MapSource
from air_sitl.maps.procedural import KINDS
from air_sitl.state import GeoPoint, Quat

DEFAULT_REFERENCE_DATE = 0
FIRST_FIX_SIGMA_M = 3.0  # the GNSS fix at the first frame (1.5 m noise, moved on to the frame)
MIN_RADIUS_M = 15.0  # search radius around the prior, at least
MAX_RADIUS_M = 150.0  # and at most (beyond: the prior is lost; keep trying at this radius)
RADIUS_SIGMAS = 3.0
RADIUS_GROWTH_M = 1.0  # per consecutive refused match: 50 m per second of refusals at 50 Hz
VAR_UP_BARO_M2 = 1.0
VAR_UP_GNSS_M2 = 9.0
# ``LocalizerContext.extras`` key: how the driver opens a reference map (``open_map``'s
# signature: spec, home, keywords seed and date); absent: :func:`air_sitl.maps.open_map`.
OPEN_MAP_EXTRA = "open_map"
MapOpener = Callable[..., MapSource]


def open_reference(context: LocalizerContext) -> MapSource:
    """The reference map a matching method uses for a flight (see the module docstring)."""
    manifest = context.manifest or {}
    info = manifest.get("map") if isinstance(manifest.get("map"), dict) else {}
    assert isinstance(info, dict)
    spec = context.reference_map
    seed = int(info.get("seed", 0) or 0)
    if spec is None and info.get("source") == "geotiff" and info.get("spec"):
        spec = str(info["spec"])  # the flight's GeoTIFF dates (a list or a folder)
    if spec is None:
        kind = info.get("kind") or context.map_name
        if info.get("source", "procedural") != "procedural" or kind not in KINDS:
            msg = (
                f"mapmatch: the flight's map ({info.get('source') or context.map_name}) is not a "
                "procedural one: give the reference map (--reference-map FILE.tif[,...])"
            )
            raise OptionError(msg)
        spec = str(kind)
    date = reference_date_for(context.map_date, context.reference_date)
    opener: MapOpener = context.extras.get(OPEN_MAP_EXTRA) or open_map
    return opener(spec, context.home, seed=seed, date=date)


def reference_date_for(flight_date: int | None, reference_date: int | None) -> int:
    """The reference map's date a map-based method matches against: the one asked for, else
    date 0, or date 1 for a flight over date 0 (never the imagery's own date by default)."""
    if reference_date is not None:
        return int(reference_date)
    return 1 if flight_date == DEFAULT_REFERENCE_DATE else DEFAULT_REFERENCE_DATE


class MapMatchBase:
    """Inputs shared by ``mapmatch`` and ``fused``: time, height, speed, prior, the matcher."""

    name = "mapmatch-base"
    needs_image = False  # frames are decoded here, in grey and reduced (the JPEG is given)
    tilt_states = False  # the filter also estimates the AHRS tilt error (``fused``)

    def __init__(
        self,
        *,
        every: int = 1,
        reference: MapSource | None = None,
        position_noise_m2_s: float = POSITION_NOISE_M2_S,
        **_: Any,
    ) -> None:
        if every < 1:
            msg = f"mapmatch every={every}: expected a positive frame interval"
            raise OptionError(msg)
        self.every = every
        self.position_noise_m2_s = position_noise_m2_s
        self._given_reference = reference
        self.matcher: MapMatcher | None = None
        self.home = GeoPoint(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0)
        self._clear()

    def _clear(self) -> None:
        self.filter = PositionFilter(
            position_noise_m2_s=self.position_noise_m2_s, tilt=self.tilt_states
        )
        self.prev_t_ns: int | None = None
        self.prev_q: Quat | None = None
        self.height_m: float | None = None
        self.gnss_height_m: float | None = None
        self.held_speed_m_s: float | None = None
        self.last_match: MatchResult | None = None
        self.matches_tried = 0
        self.matches_accepted = 0
        self.refusals = 0  # consecutive matches refused (or, in ``fused``, gated out)

    def reset(self, context: LocalizerContext) -> None:
        """Open the reference map (once per flight) and forget the previous flight."""
        self._clear()
        self.home = context.home
        reference = self._given_reference or open_reference(context)
        self.matcher = MapMatcher(reference, context.camera, context.home, **self.matcher_options())

    def matcher_options(self) -> dict[str, Any]:
        """The matcher's correlator and gate (:class:`MapMatcher` keywords; none: its own)."""
        return {}

    # -- per frame ----------------------------------------------------------------------------
    def _inputs(self, obs: Observation) -> None:
        """Predict to this frame; take the GNSS fix and the height."""
        speed = obs.airspeed_m_s if obs.airspeed_m_s is not None else self.held_speed_m_s
        if self.prev_t_ns is not None and speed is not None:
            dt = (obs.sim_time_ns - self.prev_t_ns) * 1e-9
            self.filter.predict(dt, air_velocity_en(obs, self.prev_q, speed))
        if obs.gnss is not None:
            n, e, d = fix_position_ned(obs.gnss, self.home, obs.sim_time_ns)
            if not self.filter.initialised:
                self.filter.start(e, n, FIRST_FIX_SIGMA_M)
            else:
                self.filter.update(e, n, FIRST_FIX_SIGMA_M, gate_d2=None)
            self.gnss_height_m = -d
            vn, ve = obs.gnss.vel_ned_m_s[0], obs.gnss.vel_ned_m_s[1]
            self.held_speed_m_s = math.hypot(vn, ve)
        if obs.baro_alt_rel_m is not None:
            self.height_m = obs.baro_alt_rel_m
        elif self.gnss_height_m is not None:
            self.height_m = self.gnss_height_m
        self.prev_t_ns = obs.sim_time_ns
        self.prev_q = obs.q_ahrs_body_to_ned_wxyz

    def _match(self, obs: Observation) -> MatchResult | None:
        """Try the frame against the map around the current prior (None: not tried)."""
        if self.matcher is None or not self.filter.initialised or self.height_m is None:
            return None
        if obs.frame % self.every:
            return None
        image: Any = obs.jpeg if obs.jpeg is not None else obs.image_bgr
        if image is None:
            return None
        east, north = self.filter.position
        # The radius follows the prior's uncertainty and widens while matches are refused:
        # the filter cannot know how wrong an unaided prior is (unknown wind, a bad start).
        radius = RADIUS_SIGMAS * self.filter.sigma_m + 5.0 + RADIUS_GROWTH_M * self.refusals
        radius = min(MAX_RADIUS_M, max(MIN_RADIUS_M, radius))
        try:
            result = self.matcher.match(
                image, obs.q_ahrs_body_to_ned_wxyz, self.height_m, east, north, radius
            )
        except ValueError:  # an undecodable frame: nothing to match
            return None
        self.matches_tried += 1
        if result is not None and result.accepted:
            self.matches_accepted += 1  # the subclass resets ``refusals`` when it uses it
        else:
            self.refusals += 1
        self.last_match = result
        return result

    def _var_up(self, obs: Observation) -> float:
        return VAR_UP_BARO_M2 if obs.baro_alt_rel_m is not None else VAR_UP_GNSS_M2

    def _propagated(
        self, obs: Observation, quality: float, *, fix: bool = False
    ) -> Estimate | None:
        if not self.filter.initialised or self.height_m is None:
            return None
        east, north = self.filter.position
        return Estimate(
            frame=obs.frame,
            sim_time_ns=obs.sim_time_ns,
            enu_m=(east, north, self.height_m),
            cov_enu_m2=self.filter.cov_enu(self._var_up(obs)),
            quality=quality,
            q_body_to_ned_wxyz=obs.q_ahrs_body_to_ned_wxyz,
            fix=fix,
        )


class MapMatchLocalizer(MapMatchBase):
    """Absolute fixes from map matching; dead reckoning fills refused and skipped frames."""

    name = "mapmatch"

    def step(self, obs: Observation) -> Estimate | None:
        """Match this frame; the fix, or the propagated position when refused."""
        self._inputs(obs)
        result = self._match(obs)
        if result is None or not result.accepted or self.height_m is None:
            # A propagated position ranks below any fix (>= 0.5): 0.3 between matches (every
            # k-th frame), 0 when this frame's match was refused.
            return self._propagated(obs, quality=0.3 if result is None else 0.0)
        # The fix also corrects the prior for the next frame (no gate: the quality gate is
        # this method's; ``fused`` adds an innovation gate).
        self.refusals = 0
        self.filter.update(result.east_m, result.north_m, result.sigma_m, gate_d2=None)
        var = result.sigma_m**2
        return Estimate(
            frame=obs.frame,
            sim_time_ns=obs.sim_time_ns,
            enu_m=(result.east_m, result.north_m, self.height_m),
            cov_enu_m2=(var, 0.0, 0.0, 0.0, var, 0.0, 0.0, 0.0, self._var_up(obs)),
            quality=result.quality,
            q_body_to_ned_wxyz=obs.q_ahrs_body_to_ned_wxyz,
            fix=True,
        )


__all__ = [
    "OPEN_MAP_EXTRA",
    "MapMatchBase",
    "MapMatchLocalizer",
    "MapOpener",
    "decode_gray",
    "open_reference",
]
