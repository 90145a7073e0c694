"""The onboard navigation in the loop (``--nav ekf``): simulated sensors in, estimate out.

:class:`OnboardNav` lives on the simulation thread. At every physics step the runner hands it
the truth (only to sample the extra sensors and to score the estimate), the IMU sample and the
GNSS fix (None between fixes and while denied); it feeds barometer, airspeed, magnetic heading,
GNSS and external aids to :class:`~air_sitl.nav.filter.NavFilter`, predicts with the IMU and
returns the estimate as the VehicleState the autopilot and the telemetry read.

Until the filter has its first position (the GNSS fix of t=0 reaches the fusion horizon about
0.6 s later), the autopilot reads the initial truth: a real aircraft waits on the ground for
its EKF; here an air start begins at once. Afterwards only the estimate is read (and after
2 s in any case, when neither GNSS nor an aid ever gave a position).

It also keeps what summary.json's ``nav`` block reports (horizontal error against truth, with
and without GNSS, the aid's counters), the truth cross-track (guidance's cross-track on the
estimate corrected by the estimate's error across the track), STATUSTEXT-style events (GNSS
lost/regained, aid started/lost/rejected, position failsafe) and the position failsafe:
COM_POS_FS_EPH / COM_POS_FS_ACT (0 continue and warn, 1 loiter, 2 RTL), as PX4's position-loss
actions.
"""

from __future__ import annotations

import math
from array import array
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any, Protocol

from air_sitl.nav.filter import NavFilter
from air_sitl.nav.params import NavParams
from air_sitl.nav.sensors_extra import (
    AirspeedNoise,
    AirspeedSensor,
    Barometer,
    BaroNoise,
    Magnetometer,
    MagNoise,
)
from air_sitl.nav.status import NavStatus
from air_sitl.nav.types import AidMeasurement, AidResult
from air_sitl.state import (
    AutopilotStatus,
    FlightMode,
    GeoPoint,
    GpsFix,
    ImuSample,
    NavEstimate,
    Vec3,
    VehicleState,
    vehicle_state,
)

if TYPE_CHECKING:
    from air_sitl.autopilot.autopilot import Autopilot
    from air_sitl.sensors import SensorSuite

NS_PER_S = 1_000_000_000
SCORE_PERIOD_NS = 20_000_000  # errors against truth at 50 Hz (the trajectory's rate)
REJECT_TEXT_PERIOD_NS = 5 * NS_PER_S  # STATUSTEXT on aid rejections at most this often
FAILSAFE_CLEAR_RATIO = 0.8  # the failsafe clears below 80 % of COM_POS_FS_EPH
INIT_TIMEOUT_NS = 2 * NS_PER_S  # without any position source the estimate is used after this


class AidFeed(Protocol):
    """External positions arriving from another thread (the bus)."""

    def take(self, frames_submitted: int) -> list[AidMeasurement]:
        """Measurements to fuse now (``frames_submitted``: camera frames handed out so far)."""
        ...


Event = tuple[int, str]  # (MAV_SEVERITY, text)
SEVERITY_CRITICAL = 2
SEVERITY_WARNING = 4
SEVERITY_NOTICE = 5
SEVERITY_INFO = 6


def _stats(values: array[float]) -> dict[str, float] | None:
    if not values:
        return None
    xs = sorted(values)
    n = len(xs)

    def q(p: float) -> float:
        return round(xs[min(n - 1, max(0, math.ceil(p * n) - 1))], 3)

    return {"p50": q(0.5), "p95": q(0.95), "max": round(xs[-1], 3)}


class OnboardNav:
    """The filter, its extra sensors, scoring and failsafe for one flight."""

    def __init__(
        self,
        home: GeoPoint,
        *,
        seed: int,
        noise_scale: float = 1.0,
        params: NavParams | None = None,
        gps_denied: Callable[[int], bool] = lambda _t: False,
        aid_name: str | None = None,
    ) -> None:
        self.home = home
        self.filter = NavFilter(home, params)
        f = noise_scale
        b, a, m = BaroNoise(), AirspeedNoise(), MagNoise()
        self.baro = Barometer(
            seed=seed,
            noise=replace(b, noise_m=b.noise_m * f, offset_m=b.offset_m * f,
                          drift_m_sqrt_s=b.drift_m_sqrt_s * f),
        )  # fmt: skip
        self.airspeed = AirspeedSensor(
            seed=seed, noise=replace(a, noise_m_s=a.noise_m_s * f, scale_error=a.scale_error * f)
        )
        self.mag = Magnetometer(
            seed=seed,
            noise=replace(m, noise_rad=m.noise_rad * f, offset_rad=m.offset_rad * f,
                          drift_rad_sqrt_s=m.drift_rad_sqrt_s * f),
        )  # fmt: skip
        # The extra sensors read only at multiples of their periods: at other steps none is
        # asked (each would answer None).
        self._sensor_period_ns = math.gcd(
            self.baro.period_ns, self.airspeed.period_ns, self.mag.period_ns
        )
        self.gps_denied = gps_denied
        self.aid_name = aid_name
        self.aid_feed: AidFeed | None = None
        self.autopilot: Autopilot | None = None
        self.frames_submitted = 0
        self.estimate: NavEstimate | None = None
        self.valid = False
        self._out_t = -1
        self._euler = (0.0, 0.0, 0.0)
        self._airspeed_m_s = 0.0
        self.errors = array("d")
        self.errors_denied = array("d")
        self.final_error_m: float | None = None
        self.truth_max_cross_track_m: float | None = None
        self.truth_max_cross_track_denied_m: float | None = None
        self.events: list[Event] = []
        self.event_log: list[str] = []
        self._gnss_fusing = False
        self._aid_alive: dict[str, bool] = {}
        self._aid_rejected: dict[str, int] = {}
        self._last_reject_text_ns = -REJECT_TEXT_PERIOD_NS
        self.failsafe_active = False
        self.failsafe_count = 0
        # Fuse the receiver's fixes (EKF2_GPS_CTRL bit 0 over MAVLink; read at every fix).
        self.gnss_enabled: Callable[[], bool] = lambda: True
        self.last_status: NavStatus | None = None  # at 5 Hz, for ESTIMATOR_STATUS
        self.status_wanted = False  # set by a reader of last_status (the MAVLink endpoint)
        self._ticks = 0
        self._t0: int | None = None
        self._flown: Vec3 = (0.0, 0.0, 0.0)  # the position flown on at the last 50 Hz tick

    # ------------------------------------------------------------------ the loop

    def update(self, truth: VehicleState, imu: ImuSample, gps: GpsFix | None) -> VehicleState:
        """Feed one physics step; the state the autopilot flies on at this instant."""
        nav = self.filter
        t = imu.sim_time_ns
        if truth.sim_time_ns % self._sensor_period_ns == 0:
            heading = self.mag.sample(truth)
            if heading is not None:
                nav.fuse_heading(heading, t)
            baro = self.baro.sample(truth)
            if baro is not None:
                nav.fuse_baro(baro, t)
            airspeed = self.airspeed.sample(truth)
            if airspeed is not None:
                nav.fuse_airspeed(airspeed, t)
                self._airspeed_m_s = airspeed.airspeed_m_s
        if gps is not None and self.gnss_enabled():
            nav.fuse_gnss(gps, t)
        tick = t % SCORE_PERIOD_NS == 0
        if tick and self.aid_feed is not None:
            for m in self.aid_feed.take(self.frames_submitted):
                self.fuse_aid(m, t)
        nav.predict(imu)
        if not self.valid:
            if self._t0 is None:
                self._t0 = t
            # A position, or (no GNSS nor aid from the start) 2 s: then it flies on what the
            # filter has, never on the truth for long.
            self.valid = nav.aligned and (
                (nav.pos_valid and nav.vel_valid) or t - self._t0 >= INIT_TIMEOUT_NS
            )
            if not self.valid:
                return truth
        out_t = nav.output_t_ns
        est = self.estimate
        if est is None or out_t != self._out_t:
            # A filter period passed (every 20 ms): the full estimate.
            self._out_t = out_t
            est = self.estimate = nav.estimate()
            self._euler = nav.euler(*est.q_body_to_ned_wxyz)  # frames.quat2euler, compiled
        # Between periods the attitude and velocity of the last period (at most 15 ms old),
        # the position moved on along the velocity, the rates of this IMU sample.
        dt = (t - est.sim_time_ns) * 1e-9
        p0, p1, p2 = est.pos_ned_m
        v = est.vel_ned_m_s
        v0, v1, v2 = v
        pos = (p0 + v0 * dt, p1 + v1 * dt, p2 + v2 * dt)
        if tick:
            self._flown = pos
            self._score(truth, pos)
            self._watch(t, est)
            self._ticks += 1
            if self.status_wanted and self._ticks % 10 == 0:
                self.last_status = nav.status()
        g0, g1, g2 = imu.gyro_frd_rad_s
        bg0, bg1, bg2 = est.gyro_bias_rad_s
        f0, f1, f2 = imu.accel_frd_m_s2
        ba0, ba1, ba2 = est.accel_bias_m_s2
        roll, pitch, yaw = self._euler
        alt = est.alt_amsl_m - v2 * dt
        tas = self._airspeed_m_s if self._airspeed_m_s > 0.0 else truth.airspeed_m_s
        return vehicle_state(  # positional, in VehicleState's field order (a 200 Hz path)
            t,
            est.lat_deg,
            est.lon_deg,
            alt,
            alt - self.home.alt_amsl_m,
            pos,
            est.q_body_to_ned_wxyz,
            roll,
            pitch,
            yaw,
            v,
            (g0 - bg0, g1 - bg1, g2 - bg2),  # body rates
            (f0 - ba0, f1 - ba1, f2 - ba2),  # specific force
            tas,
            truth.on_ground,  # weight on wheels: a switch, not an estimate
        )

    @property
    def now_ns(self) -> int:
        """The newest IMU time: "now" for a measurement arriving from outside."""
        t = self.filter._t_imu
        return 0 if t is None else t

    def fuse_aid(self, m: AidMeasurement, now_ns: int) -> AidResult:
        """One external position (simulation thread: the bus feed or the MAVLink inbox)."""
        return self.filter.fuse_aid(m, now_ns)

    def observe(self, truth: VehicleState, status: AutopilotStatus) -> None:
        """After the autopilot's update: the truth cross-track of the tracked segment."""
        est = self.estimate
        if truth.sim_time_ns % SCORE_PERIOD_NS or est is None:
            return  # at 50 Hz, the guidance rate
        if not status.tracking_settled or math.isnan(status.cross_track_m):
            return
        vn, ve = est.vel_ned_m_s[0], est.vel_ned_m_s[1]
        gs = math.hypot(vn, ve)
        if gs < 1.0:
            return
        # Guidance's cross-track is positive right of the direction of travel; the estimate's
        # error across the track moves the true aircraft by that much.
        dn = truth.pos_ned_m[0] - self._flown[0]
        de = truth.pos_ned_m[1] - self._flown[1]
        xt = abs(status.cross_track_m + (-dn * ve + de * vn) / gs)
        self.truth_max_cross_track_m = max(self.truth_max_cross_track_m or 0.0, xt)
        if self.gps_denied(truth.sim_time_ns):
            self.truth_max_cross_track_denied_m = max(
                self.truth_max_cross_track_denied_m or 0.0, xt
            )

    def _score(self, truth: VehicleState, pos: Vec3) -> None:
        err = math.hypot(pos[0] - truth.pos_ned_m[0], pos[1] - truth.pos_ned_m[1])
        self.errors.append(err)
        if self.gps_denied(truth.sim_time_ns):
            self.errors_denied.append(err)
        self.final_error_m = err

    # ------------------------------------------------------------------ events, failsafe

    def _event(self, t_ns: int, severity: int, text: str) -> None:
        self.events.append((severity, text))
        self.event_log.append(f"{t_ns / NS_PER_S:.1f} s: {text}")

    def pop_events(self) -> list[Event]:
        """STATUSTEXT-style (severity, text) since the last call."""
        out, self.events = self.events, []
        return out

    def _watch(self, t: int, est: NavEstimate) -> None:
        nav = self.filter
        fusing = est.flags.gnss_fusing
        if fusing != self._gnss_fusing:
            self._gnss_fusing = fusing
            if fusing:
                self._event(t, SEVERITY_INFO, "GNSS fused: position from GNSS")
            else:
                self._event(t, SEVERITY_WARNING, "GNSS lost: navigation without GNSS")
        for name, aid in nav.aids.items():
            alive = aid.alive(t)
            if alive != self._aid_alive.get(name, False):
                self._aid_alive[name] = alive
                if alive:
                    self._event(t, SEVERITY_INFO, f"aid {name} started")
                else:
                    self._event(t, SEVERITY_WARNING, f"aid {name} lost (no position for 1 s)")
            rejected = aid.counters.rejected
            if rejected > self._aid_rejected.get(name, 0):
                self._aid_rejected[name] = rejected
                if t - self._last_reject_text_ns >= REJECT_TEXT_PERIOD_NS:
                    self._last_reject_text_ns = t
                    reasons = ", ".join(f"{k} {v}" for k, v in sorted(aid.counters.reasons.items()))
                    self._event(t, SEVERITY_NOTICE, f"aid {name}: rejected {rejected} ({reasons})")
        self._failsafe(t, est)

    def _failsafe(self, t: int, est: NavEstimate) -> None:
        ap = self.autopilot
        if ap is None:
            return
        params = ap.params
        limit = params.get("COM_POS_FS_EPH")
        if self.failsafe_active:
            if est.std_h_m < FAILSAFE_CLEAR_RATIO * limit:
                self.failsafe_active = False
                self._event(t, SEVERITY_INFO, f"position regained ({est.std_h_m:.1f} m)")
            return
        if est.std_h_m <= limit:
            return
        self.failsafe_active = True
        self.failsafe_count += 1
        action = int(params.get("COM_POS_FS_ACT"))
        airborne = ap.armed and ap.mode not in (FlightMode.IDLE, FlightMode.LAND)
        what = "continuing the mission"
        if airborne and action == 1 and ap.mode is not FlightMode.LOITER:
            ap.set_mode(FlightMode.LOITER)
            what = "loiter"
        elif airborne and action == 2 and ap.mode is not FlightMode.RTL:
            ap.return_to_launch()
            what = "return to launch"
        self._event(
            t,
            SEVERITY_CRITICAL,
            f"position uncertain: {est.std_h_m:.1f} m > COM_POS_FS_EPH {limit:g} m: {what}",
        )

    # ------------------------------------------------------------------ summary

    def summary(self) -> dict[str, Any]:
        """summary.json's ``truth_max_cross_track_m`` and ``nav`` block."""
        status = self.filter.status()
        aid: dict[str, Any] | None = None
        if self.aid_name is not None:
            # One aid, or (MAVLink) every "NAME:kind" aid summed.
            prefix = self.aid_name + ":"
            found = [a for a in status.aids if a.name == self.aid_name or a.name.startswith(prefix)]
            aid = {"name": self.aid_name, "received": 0, "fused": 0, "rejected": 0, "empty": 0}
            reasons: dict[str, int] = {}
            resets = 0
            for a in found:
                for key in ("received", "fused", "rejected", "empty"):
                    aid[key] += getattr(a, key)
                resets += a.resets
                for k, v in a.rejected_by_reason.items():
                    reasons[k] = reasons.get(k, 0) + v
            aid.update(resets=resets, rejected_by_reason=dict(sorted(reasons.items())))
        rounded = self.truth_max_cross_track_m
        denied_xt = self.truth_max_cross_track_denied_m
        return {
            "truth_max_cross_track_m": None if rounded is None else round(rounded, 3),
            "nav": {
                "source": "ekf",
                "horizontal_error_m": _stats(self.errors),
                "horizontal_error_denied_m": _stats(self.errors_denied),
                "final_horizontal_error_m": None
                if self.final_error_m is None
                else round(self.final_error_m, 3),
                "gnss_denied_s": round(status.gnss_denied_s, 3),
                "truth_max_cross_track_denied_m": None
                if denied_xt is None
                else round(denied_xt, 3),
                "aid": aid,
                "failsafes": self.failsafe_count,
                "events": self.event_log[:100],
            },
        }


def denied_s(windows: tuple[tuple[int, int], ...], sim_time_ns: int) -> float:
    """Seconds of the flight inside GNSS denial windows."""
    ns = sum(max(0, min(b, sim_time_ns) - a) for a, b in windows if a < sim_time_ns)
    return round(ns / NS_PER_S, 3)


def truth_nav_summary(
    summary: dict[str, Any], sensors: SensorSuite, sim_time_ns: int
) -> dict[str, Any]:
    """The same keys for ``--nav truth``: the autopilot flew on the truth (no error)."""
    return {
        "truth_max_cross_track_m": summary.get("max_cross_track_m"),
        "nav": {
            "source": "truth",
            "horizontal_error_m": None,
            "horizontal_error_denied_m": None,
            "gnss_denied_s": denied_s(sensors.gps_denied_ns, sim_time_ns),
            "aid": None,
        },
    }
