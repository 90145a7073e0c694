"""NavFilter: the public face of the onboard navigation filter.

Feed it every IMU sample (``predict``) and each measurement when it arrives (``fuse_*``);
read ``estimate()`` (the state now, from the output predictor) and ``status()`` (counters,
flags, test ratios). Measurements are buffered and fused when the delayed filter, which runs
``fusion_horizon_ns`` behind the newest IMU sample, reaches their own time.
"""

from __future__ import annotations

import math
from typing import Protocol, TypeVar

import numpy as np

from air_sitl.frames import LocalNed, euler2quat
from air_sitl.nav.aid import AidControl
from air_sitl.nav.airspeed import AirspeedControl
from air_sitl.nav.baro import BaroControl
from air_sitl.nav.ekf import POS, VEL, ErrorStateEkf, normal_gravity_m_s2
from air_sitl.nav.gnss import GnssControl
from air_sitl.nav.mag import MagControl
from air_sitl.nav.params import NavParams
from air_sitl.nav.status import AidStatus, NavStatus, SourceCounters
from air_sitl.nav.types import (
    AidMeasurement,
    AidResult,
    AirspeedSample,
    BaroSample,
    HeadingSample,
)
from air_sitl.nav.vehicle import nav_estimate
from air_sitl.state import GeoPoint, GpsFix, ImuSample, NavEstimate, NavFlags


class _Stamped(Protocol):
    @property
    def sim_time_ns(self) -> int: ...


S_contra = TypeVar("S_contra", bound=_Stamped, contravariant=True)
S = TypeVar("S", bound=_Stamped)


class _Source(Protocol[S_contra]):
    """A source's buffer of measurements: GNSS, barometer, airspeed, compass."""

    def push(self, sample: S_contra, now_ns: int, horizon_start_ns: int) -> bool: ...


MAX_AIDS = 16
REPLAY_PERIOD_NS = 1_000_000_000
UNKNOWN_POS_M = 100.0
UNKNOWN_VEL_M_S = 30.0


class NavFilter:
    """Error-state EKF (position, velocity, attitude, gyro/accel biases, horizontal wind)."""

    def __init__(self, home: GeoPoint, params: NavParams | None = None) -> None:
        self.home = home
        self.params = p = params or NavParams()
        self.g = g = normal_gravity_m_s2(home.lat_deg, home.alt_amsl_m)
        self.ekf = ekf = ErrorStateEkf(p, g)
        from air_sitl.nav import geodetic  # compiled, as ErrorStateEkf's kernels: loaded now

        self._local = LocalNed(
            home.lat_deg, home.lon_deg, home.alt_amsl_m, lat_alt=geodetic.lat_alt
        )
        # The estimate's attitude as ZYX Euler angles (frames.quat2euler, compiled).
        self.euler = geodetic.euler
        self._strapdown = sd = ekf.strapdown
        # The output predictor (the state at the newest filter period, see strapdown), the
        # ring of IMU deltas the delayed filter has not reached yet, and its indices.
        self.output = np.zeros(sd.NO)
        self.output[6] = 1.0
        self.output_t_ns = 0
        ring_len = p.fusion_horizon_ns // p.filter_period_ns + 8
        self._ring = np.zeros((ring_len, sd.RING_COLS))
        self._ring_index = np.zeros(2 + ring_len, dtype=np.int64)
        self._last = np.zeros(sd.LAST)  # the output's running sums at the delayed time
        self._estimate = np.zeros(sd.NE)
        self.gnss = GnssControl(p, home)
        self.baro = BaroControl(p, home.alt_amsl_m)
        self.airspeed = AirspeedControl(p)
        self.mag = MagControl(p)
        self.aids: dict[str, AidControl] = {}
        self.aid_overflow = SourceCounters()
        self.aligned = False
        self.pos_valid = False
        self.vel_valid = False
        self.gnss_denied_ns = 0
        self._t_imu: int | None = None
        self._t_delayed: int | None = None
        self._last_replay_ns = 0
        self._align = [0.0, 0.0, 0.0]
        self._align_n = 0
        self._acc = [0.0] * 6
        self._acc_dt = 0.0
        self._acc_t0 = 0
        self._period_ns = p.filter_period_ns
        self._horizon_ns = p.fusion_horizon_ns
        self._imu_dt = p.imu_period_ns * 1e-9
        self._flags_key: tuple[bool, ...] = ()  # of _flags_now (none yet: never equal)
        self._flags_now = NavFlags(**dict.fromkeys(NavFlags.__dataclass_fields__, False))

    # ------------------------------------------------------------------ prediction

    def predict(self, imu: ImuSample) -> None:
        """One IMU sample (200 Hz): sum it; every filter period run the output predictor
        and the delayed filter up to the fusion horizon."""
        t = imu.sim_time_ns
        last = self._t_imu
        if last is None:
            dt = self._imu_dt
        else:
            if t <= last:
                return  # duplicate or out of order: ignored
            dt = (t - last) * 1e-9
            if dt > 0.1:
                dt = self._imu_dt  # a gap: do not integrate across it
        self._t_imu = t
        if not self.aligned:
            self._align_step(t, imu.accel_frd_m_s2)
            return
        g0, g1, g2 = imu.gyro_frd_rad_s
        f0, f1, f2 = imu.accel_frd_m_s2
        a = self._acc
        a[0] += g0 * dt
        a[1] += g1 * dt
        a[2] += g2 * dt
        a[3] += f0 * dt
        a[4] += f1 * dt
        a[5] += f2 * dt
        self._acc_dt += dt
        if t - self._acc_t0 >= self._period_ns:
            self._push_delta(t)

    def _push_delta(self, t: int) -> None:
        """One filter period: the output predictor and the ring, then the delayed filter over
        every delta the horizon has reached (one, in steady flight)."""
        a = self._acc
        ekf, sd, ring, ri = self.ekf, self._strapdown, self._ring, self._ring_index
        due = sd.advance(
            self.output, ekf.x, ring, ri, t, a[0], a[1], a[2], a[3], a[4], a[5], self._acc_dt,
            self.g,
        )  # fmt: skip
        self.output_t_ns = t
        self._acc = [0.0] * 6
        self._acc_dt = 0.0
        self._acc_t0 = t
        horizon = t - self._horizon_ns
        while due <= horizon:
            t_d, dt, due = sd.delayed_predict(
                ekf.x, ekf.P, ekf.cov, ring, ri, ekf.consts, self._last
            )
            self._delayed_step(t_d, dt)

    def _delayed_step(self, t_d: int, dt: float) -> None:
        """After the delayed state's prediction to ``t_d``: the measurements due, then the
        corrections carried to the output predictor (or, once a second, the output replayed)."""
        ekf = self.ekf
        self._t_delayed = t_d
        # A source is asked only once the horizon has reached its oldest measurement.
        if self.mag.buffer.due_ns <= t_d:
            self.mag.fuse_due(ekf, t_d)
        if self.baro.buffer.due_ns <= t_d:
            self.baro.fuse_due(ekf, t_d, self.gnss.last_alt_amsl_m)
        gnss = self.gnss
        if gnss.buffer.due_ns <= t_d:
            self._fuse_gnss_due(t_d)
        if self.aids:
            self._fuse_aids_due(t_d)
        if self.airspeed.buffer.due_ns <= t_d:
            self.airspeed.fuse_due(ekf, t_d, self.vel_valid)
            if self.airspeed.wind_started and not self.vel_valid:
                self.vel_valid = True
        if gnss.started and not gnss.fusing(t_d):
            self.gnss_denied_ns += round(dt * 1e9)
        if t_d - self._last_replay_ns >= REPLAY_PERIOD_NS:
            self._last_replay_ns = t_d
            self.replay_output()
        elif ekf.corrected:
            window_s = (self.output_t_ns - t_d) * 1e-9
            self._strapdown.carry(self.output, ekf.pending, window_s, self._last)
        ekf.corrected = False

    def replay_output(self) -> None:
        """Recompute the output predictor exactly: the delayed state advanced over the ring."""
        ekf, ring, ri = self.ekf, self._ring, self._ring_index
        self._strapdown.replay(self.output, ekf.x, ring, ri, self.g, ekf.pending)

    def _fuse_gnss_due(self, t_d: int) -> None:
        gnss = self.gnss
        was_started = gnss.started
        fused_before = gnss.counters.fused
        last_ns = gnss.last_fused_ns
        gnss.fuse_due(self.ekf, t_d)
        if gnss.started and not was_started:
            self.pos_valid = self.vel_valid = True
        if gnss.counters.fused > fused_before and gnss.last_alt_amsl_m is not None:
            dt = 0.0 if last_ns is None else (t_d - last_ns) * 1e-9
            self.baro.calibrate(gnss.last_alt_amsl_m, gnss.last_epv_m**2, dt)

    def _fuse_aids_due(self, t_d: int) -> None:
        gnss_fusing = self.gnss.fusing(t_d)
        now = self._t_imu or t_d
        for name, aid in self.aids.items():
            if not aid.alive(now):
                aid.lost()
            if aid.buffer.due_ns > t_d:
                continue  # nothing for the horizon yet
            others = gnss_fusing or any(
                other.fusing(t_d) for n, other in self.aids.items() if n != name
            )
            if aid.fuse_due(self.ekf, t_d, not others, self.pos_valid):
                self.pos_valid = True

    def _align_step(self, t: int, f: tuple[float, float, float]) -> None:
        """Tilt from the mean specific force (unaccelerated flight), yaw from the compass."""
        a = self._align
        a[0] += f[0]
        a[1] += f[1]
        a[2] += f[2]
        self._align_n += 1
        if self._align_n < self.params.align_samples:
            return
        fx, fy, fz = (x / self._align_n for x in a)
        roll = math.atan2(-fy, -fz)
        pitch = math.atan2(fx, math.hypot(fy, fz))
        heading = self.mag.last_heading_rad
        yaw = 0.0 if heading is None else heading + self.params.mag_declination_rad
        ekf = self.ekf
        ekf.q = euler2quat(roll, pitch, yaw)
        ekf.init_covariance()
        for k in range(3):
            ekf.P[POS + k, POS + k] = UNKNOWN_POS_M**2
            ekf.P[VEL + k, VEL + k] = UNKNOWN_VEL_M_S**2
        if heading is None:
            ekf.P[8, 8] = math.pi**2
        ekf.pending.fill(0.0)
        ekf.corrected = False
        self.output[0:10] = ekf.x[0:10]
        self.output_t_ns = t
        self.aligned = True
        self._acc_t0 = t
        self._t_delayed = t
        self._last_replay_ns = t

    # ------------------------------------------------------------------ measurements

    def _horizon_start(self, now_ns: int) -> int:
        start = now_ns - self._horizon_ns
        if self._t_delayed is not None:
            start = max(start, self._t_delayed + 1)
        return start

    def _buffer(self, source: _Source[S], sample: S, now_ns: int | None) -> bool:
        """Hand a measurement to its source with the arrival time (default: the newest IMU
        time) and the start of the delayed horizon then."""
        if now_ns is None:
            now_ns = self._t_imu if self._t_imu is not None else sample.sim_time_ns
        return source.push(sample, now_ns, self._horizon_start(now_ns))

    def fuse_gnss(self, fix: GpsFix, now_ns: int | None = None) -> bool:
        """Buffer one GNSS fix (arrived at ``now_ns``, default: the newest IMU time)."""
        return self._buffer(self.gnss, fix, now_ns)

    def fuse_baro(self, sample: BaroSample, now_ns: int | None = None) -> bool:
        return self._buffer(self.baro, sample, now_ns)

    def fuse_airspeed(self, sample: AirspeedSample, now_ns: int | None = None) -> bool:
        return self._buffer(self.airspeed, sample, now_ns)

    def fuse_heading(self, sample: HeadingSample, now_ns: int | None = None) -> bool:
        return self._buffer(self.mag, sample, now_ns)

    def fuse_aid(self, measurement: AidMeasurement, now_ns: int) -> AidResult:
        """Check and buffer one external position (never raises on bad content).

        ``now_ns`` is the simulated time of arrival; the measurement's own ``sim_time_ns`` is
        the time it refers to (at most ``fusion_horizon_ns`` before ``now_ns``).
        """
        name = getattr(measurement, "name", None)
        if not isinstance(name, str):
            name = "?"
        aid = self.aids.get(name)
        if aid is None:
            if len(self.aids) >= MAX_AIDS:
                self.aid_overflow.received += 1
                self.aid_overflow.reject("too_many_aids")
                return AidResult.REJECTED_INVALID
            aid = self.aids[name] = AidControl(name, self.params, self.home)
        try:
            return aid.push(measurement, now_ns, self._horizon_start(now_ns))
        except (AttributeError, TypeError, ValueError, OverflowError):
            # Not an AidMeasurement at all (a bus payload parsed wrong): counted, not raised.
            aid.counters.reject(AidResult.REJECTED_INVALID.value)
            return AidResult.REJECTED_INVALID

    # ------------------------------------------------------------------ outputs

    def _flags(self) -> NavFlags:
        t_d = self._t_delayed or 0
        gnss = self.gnss.fusing(t_d)
        aid = bool(self.aids) and any(a.fusing(t_d) for a in self.aids.values())
        key = (
            self.aligned, self.vel_valid, self.pos_valid, gnss, aid, self.baro.started,
            self.airspeed.wind_started,
        )  # fmt: skip
        if key != self._flags_key:  # they change a few times a flight: one object each time
            self._flags_key = key
            self._flags_now = NavFlags(
                attitude=self.aligned,
                velocity_horiz=self.vel_valid,
                velocity_vert=self.aligned,
                pos_horiz_rel=self.pos_valid,
                pos_horiz_abs=gnss or aid,
                pos_vert_abs=self.baro.started,
                gnss_fusing=gnss,
                aid_fusing=aid,
                dead_reckoning=self.pos_valid and not (gnss or aid),
                wind_estimated=self.airspeed.wind_started,
            )
        return self._flags_now

    def estimate(self) -> NavEstimate:
        """The state at the newest IMU time: the output predictor advanced over the IMU
        samples summed since its last step (fewer than one filter period)."""
        ekf = self.ekf
        t = self._t_imu if self._t_imu is not None else 0
        s = self._acc
        dt = self._acc_dt if self.aligned else 0.0
        res = self._estimate
        self._strapdown.output_estimate(
            self.output, ekf.x, ekf.P, s[0], s[1], s[2], s[3], s[4], s[5], dt, self.g, res
        )
        r = res.tolist()
        lat, lon, alt = self._local.to_geodetic(r[0], r[1], r[2])
        return nav_estimate(  # positional, in NavEstimate's field order (every filter period)
            t,
            (r[0], r[1], r[2]),
            (r[3], r[4], r[5]),
            (r[6], r[7], r[8], r[9]),
            lat,
            lon,
            alt,
            r[10],
            r[11],
            (r[12], r[13]),
            (r[14], r[15], r[16]),
            (r[17], r[18], r[19]),
            self._flags(),
        )

    def status(self) -> NavStatus:
        t_d = self._t_delayed or 0
        flags = self._flags()
        if flags.gnss_fusing:
            source = "gnss"
        elif flags.aid_fusing:
            names = sorted(n for n, a in self.aids.items() if a.fusing(t_d))
            source = "aid:" + ",".join(names)
        elif flags.dead_reckoning:
            source = "dead_reckoning"
        else:
            source = "none"
        P = self.ekf.P
        aids = tuple(
            AidStatus.of(n, a.counters, fusing=a.fusing(t_d)) for n, a in sorted(self.aids.items())
        )
        return NavStatus(
            sim_time_ns=self._t_imu or 0,
            source=source,
            gnss_denied_s=self.gnss_denied_ns * 1e-9,
            flags=flags,
            gnss=AidStatus.of("gnss", self.gnss.counters, fusing=flags.gnss_fusing),
            baro=AidStatus.of("baro", self.baro.counters, fusing=self.baro.fusing(t_d)),
            airspeed=AidStatus.of(
                "airspeed", self.airspeed.counters, fusing=self.airspeed.wind_started
            ),
            heading=AidStatus.of("heading", self.mag.counters, fusing=self.mag.started),
            aids=aids,
            vel_ratio=self.gnss.vel_ratio,
            pos_horiz_ratio=max(
                [self.gnss.pos_ratio] + [a.counters.test_ratio for a in self.aids.values()]
            ),
            pos_vert_ratio=self.baro.ratio,
            mag_ratio=self.mag.ratio,
            tas_ratio=self.airspeed.tas_ratio,
            beta_ratio=self.airspeed.beta_ratio,
            pos_horiz_accuracy_m=math.sqrt(max(float(P[0, 0] + P[1, 1]), 0.0)),
            pos_vert_accuracy_m=math.sqrt(max(float(P[2, 2]), 0.0)),
        )

    def horizontal_covariance(self) -> tuple[float, float, float]:
        """(var_n, cov_ne, var_e) of the delayed state, m^2 (consistency checks)."""
        P = self.ekf.P
        return float(P[0, 0]), float(P[0, 1]), float(P[1, 1])
