"""``deadreckon``: the floor. AHRS heading, airspeed along it, barometric height; no vision.

The position starts at the first GNSS fix and integrates ``airspeed x heading`` over every IMU
sample (the AHRS heading at 200 Hz; between frames when the IMU samples are missing). Wind is
unknown: it is taken as zero unless GNSS keeps coming (an archive with denial windows): then
the wind is the running mean of ``GNSS velocity - airspeed x heading`` over the fixes
(at least :data:`WIND_MIN_FIXES` of them, so that a single noisy fix does not turn into a
constant velocity error), and every fix resets the position. Height: the barometer, or
without one (the bus) the height of the last GNSS fix, held. Airspeed: the pitot, or without
one (the bus) the ground speed of the last GNSS fix, held (equal to the airspeed in calm air).
"""

from __future__ import annotations

import math

from air_sitl.frames import quat2euler
from air_sitl.localize.base import Estimate, GnssFix, LocalizerContext, Observation
from air_sitl.localize.inputs import fix_position_ned
from air_sitl.state import GeoPoint, Quat

WIND_MIN_FIXES = 25  # 5 s of 5 Hz fixes before a wind estimate replaces "no wind"
FIX_SIGMA_M = 1.5  # horizontal GNSS noise
DRIFT_SIGMA_FRACTION = 0.05  # assumed 1-sigma growth: 5 % of the distance flown since the fix


def _heading_rad(q: Quat) -> float:
    return quat2euler(q)[2]


class DeadReckoning:
    """IMU/AHRS + airspeed + barometer dead reckoning from the initial fix."""

    name = "deadreckon"
    needs_image = False
    reads_imagery = False  # neither frames nor map: the same estimates over every map date

    def __init__(self) -> None:
        self.home = GeoPoint(lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0)
        self._clear()

    def _clear(self) -> None:
        self.north_m: float | None = None
        self.east_m = 0.0
        self.height_m: float | None = None
        self.gnss_height_m: float | None = None
        self.speed_m_s: float | None = None  # held GNSS ground speed (no airspeed sensor)
        self.wind_sum_ne = (0.0, 0.0)
        self.wind_fixes = 0
        self.since_fix_m = 0.0
        self.prev_t_ns: int | None = None
        self.prev_heading: float | None = None

    def reset(self, context: LocalizerContext) -> None:
        """Forget the previous flight."""
        self._clear()
        self.home = context.home

    @property
    def wind_ne_m_s(self) -> tuple[float, float]:
        """The wind the method assumes (north, east)."""
        if self.wind_fixes < WIND_MIN_FIXES:
            return (0.0, 0.0)
        return (self.wind_sum_ne[0] / self.wind_fixes, self.wind_sum_ne[1] / self.wind_fixes)

    def _fix(self, fix: GnssFix, t_ns: int, heading: float, airspeed: float | None) -> None:
        n, e, d = fix_position_ned(fix, self.home, t_ns)
        self.north_m, self.east_m = n, e
        self.since_fix_m = 0.0
        self.gnss_height_m = -d
        vn, ve = fix.vel_ned_m_s[0], fix.vel_ned_m_s[1]
        self.speed_m_s = math.hypot(vn, ve)
        if airspeed is not None:
            self.wind_sum_ne = (
                self.wind_sum_ne[0] + vn - airspeed * math.cos(heading),
                self.wind_sum_ne[1] + ve - airspeed * math.sin(heading),
            )
            self.wind_fixes += 1

    def step(self, obs: Observation) -> Estimate | None:
        """Integrate from the previous frame to this one."""
        heading = _heading_rad(obs.q_ahrs_body_to_ned_wxyz)
        speed = obs.airspeed_m_s if obs.airspeed_m_s is not None else self.speed_m_s
        if self.north_m is not None and self.prev_t_ns is not None and speed is not None:
            self._integrate(obs, heading, speed)
        if obs.gnss is not None:
            self._fix(obs.gnss, obs.sim_time_ns, heading, obs.airspeed_m_s)
        self.prev_t_ns = obs.sim_time_ns
        self.prev_heading = heading
        if obs.baro_alt_rel_m is not None:
            self.height_m = obs.baro_alt_rel_m
        elif obs.gnss is not None:
            self.height_m = self.gnss_height_m
        if self.north_m is None or self.height_m is None:
            return None
        sigma_h = FIX_SIGMA_M + DRIFT_SIGMA_FRACTION * self.since_fix_m
        var_h = sigma_h * sigma_h
        var_v = 1.0 if obs.baro_alt_rel_m is not None else 9.0
        return Estimate(
            frame=obs.frame,
            sim_time_ns=obs.sim_time_ns,
            enu_m=(self.east_m, self.north_m, self.height_m),
            cov_enu_m2=(var_h, 0.0, 0.0, 0.0, var_h, 0.0, 0.0, 0.0, var_v),
            q_body_to_ned_wxyz=obs.q_ahrs_body_to_ned_wxyz,
        )

    def _integrate(self, obs: Observation, heading: float, speed: float) -> None:
        assert self.north_m is not None and self.prev_t_ns is not None
        wn, we = self.wind_ne_m_s
        t_prev = self.prev_t_ns
        samples = [s for s in obs.imu if t_prev < s.sim_time_ns <= obs.sim_time_ns]
        if samples and samples[-1].sim_time_ns == obs.sim_time_ns:
            # The AHRS heading over each IMU interval (rectangle rule at 200 Hz).
            steps = [(s.sim_time_ns, _heading_rad(s.q_ahrs_body_to_ned_wxyz)) for s in samples]
        else:
            # IMU samples missing (a lossy bus): the mean heading between the two frames.
            prev = self.prev_heading if self.prev_heading is not None else heading
            mid = prev + 0.5 * math.remainder(heading - prev, math.tau)
            steps = [(obs.sim_time_ns, mid)]
        north, east = self.north_m, self.east_m
        for t_ns, psi in steps:
            dt = (t_ns - t_prev) * 1e-9
            north += (speed * math.cos(psi) + wn) * dt
            east += (speed * math.sin(psi) + we) * dt
            self.since_fix_m += speed * dt
            t_prev = t_ns
        self.north_m, self.east_m = north, east
