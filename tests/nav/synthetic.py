"""A scripted straight-and-level flight with ideal sensors: fast filter tests without JSBSim."""

from __future__ import annotations

import math

from air_sitl.frames import ned2geodetic
from air_sitl.nav import NavFilter, NavParams
from air_sitl.nav.ekf import normal_gravity_m_s2
from air_sitl.nav.types import AirspeedSample, BaroSample, HeadingSample
from air_sitl.state import GeoPoint, GpsFix, ImuSample

HOME = GeoPoint(lat_deg=38.5125, lon_deg=-121.4935, alt_amsl_m=7.0)
STEP_NS = 5_000_000
SPEED_M_S = 15.0  # due north, 200 m above home, calm air
HEIGHT_M = 200.0
NS = 1_000_000_000


def truth_ned(t_ns: int) -> tuple[float, float, float]:
    return (SPEED_M_S * t_ns / NS, 0.0, -HEIGHT_M)


class Straight:
    """Drives a NavFilter along the straight line; ``gnss`` can be switched off."""

    def __init__(self, params: NavParams | None = None) -> None:
        self.nav = NavFilter(HOME, params)
        self.t_ns = 0
        self.gnss = True
        self.baro_offset_m = 0.0
        self._g = normal_gravity_m_s2(HOME.lat_deg, HOME.alt_amsl_m)

    def step(self) -> None:
        t = self.t_ns
        nav = self.nav
        if t % 100_000_000 == 0:
            nav.fuse_heading(HeadingSample(sim_time_ns=t, heading_rad=0.0), t)
            nav.fuse_airspeed(AirspeedSample(sim_time_ns=t, airspeed_m_s=SPEED_M_S), t)
            nav.fuse_baro(
                BaroSample(
                    sim_time_ns=t, alt_amsl_m=HOME.alt_amsl_m + HEIGHT_M + self.baro_offset_m
                ),
                t,
            )
        if self.gnss and t % 200_000_000 == 0:
            n, e, d = truth_ned(t)
            lat, lon, alt = ned2geodetic(n, e, d, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
            nav.fuse_gnss(
                GpsFix(
                    sim_time_ns=t,
                    lat_deg=lat,
                    lon_deg=lon,
                    alt_amsl_m=alt,
                    vel_ned_m_s=(SPEED_M_S, 0.0, 0.0),
                    fix_type=3,
                    satellites=14,
                    eph_m=1.5,
                    epv_m=3.0,
                ),
                t,
            )
        nav.predict(
            ImuSample(
                sim_time_ns=t,
                gyro_frd_rad_s=(0.0, 0.0, 0.0),
                accel_frd_m_s2=(0.0, 0.0, -self._g),
                q_ahrs_body_to_ned_wxyz=(1.0, 0.0, 0.0, 0.0),
            )
        )
        self.t_ns += STEP_NS

    def run(self, seconds: float) -> None:
        for _ in range(round(seconds * NS / STEP_NS)):
            self.step()

    def error_m(self) -> float:
        e = self.nav.estimate()
        n, east, _ = truth_ned(e.sim_time_ns)
        return math.hypot(e.pos_ned_m[0] - n, e.pos_ned_m[1] - east)
