"""The onboard navigation over MAVLink: position aids in, the estimate's truth out.

In (``serve --nav-aid mavlink``), from any link and any sender (a companion computer uses its
own ids, e.g. 1/197), decoded on the I/O thread and fused on the simulation thread:

- VISION_POSITION_ESTIMATE and ODOMETRY: external vision, PX4 EKF2_EV_* meaning. Positions are
  local NED from home (ODOMETRY ``frame_id`` MAV_FRAME_LOCAL_NED; MAV_FRAME_LOCAL_ENU is taken
  as ENU; any other frame, MAV_FRAME_LOCAL_FRD included, is rejected as unknown: we do no frame
  alignment). ``usec``/``time_usec`` is simulated time since boot. The covariance is used when
  EKF2_EV_NOISE_MD is 0 and its first element is finite, else EKF2_EVP_NOISE (the aid sigma).
  Fused only while bit 0 (horizontal position) of EKF2_EV_CTRL is set; with ``--nav-aid
  mavlink`` it is by default.
- GLOBAL_POSITION_SENSOR and GPS_INPUT: latitude/longitude (degE7), ``eph`` /
  ``horiz_accuracy`` as the 1-sigma (else EKF2_EVP_NOISE); a GPS_INPUT with fix_type < 2 has no
  position (empty). These are the auxiliary global position of EKF2 (EKF2_AGP_*), always fused
  with ``--nav-aid mavlink``.

The aids are named ``mavlink:ev`` and ``mavlink:global`` in the filter and summary.json.
EKF2_GPS_CTRL bit 0 off keeps the receiver's fixes out of the filter (as PX4's). Parameters are
read live at every message.

Out: GLOBAL_POSITION_INT, LOCAL_POSITION_NED, ATTITUDE, ATTITUDE_QUATERNION and VFR_HUD from the
estimate (the truth stays on the zenoh ``truth`` key and in the archive); GPS_RAW_INT with
fix_type 0 while the receiver has no fix (denied); ESTIMATOR_STATUS (flags, test ratios,
accuracies) at 5 Hz; STATUSTEXT on GNSS lost/regained, aid started/lost, rejections
(rate-limited) and the position failsafe.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

from air_sitl.mavlink import telemetry as tm
from air_sitl.mavlink.codec import Message, mav
from air_sitl.nav.types import AidFrame, AidMeasurement
from air_sitl.nav.vehicle import estimated_state
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, GpsFix, SimSample

if TYPE_CHECKING:
    from air_sitl.autopilot.params import ParamStore
    from air_sitl.mavlink.interfaces import Builder, EndpointLike
    from air_sitl.mavlink.links import Channel
    from air_sitl.nav.onboard import OnboardNav

EV_AID = "mavlink:ev"
GLOBAL_AID = "mavlink:global"
NO_FIX_AFTER_NS = 1_000_000_000  # GPS_RAW_INT says "no fix" when the last fix is this old
EVENT_PERIOD_NS = 50_000_000
ESTIMATOR_STATUS_HZ = 5.0

# ESTIMATOR_STATUS_FLAGS
_FLAG_BITS = (
    ("attitude", mav.ESTIMATOR_ATTITUDE),
    ("velocity_horiz", mav.ESTIMATOR_VELOCITY_HORIZ),
    ("velocity_vert", mav.ESTIMATOR_VELOCITY_VERT),
    ("pos_horiz_rel", mav.ESTIMATOR_POS_HORIZ_REL),
    ("pos_horiz_abs", mav.ESTIMATOR_POS_HORIZ_ABS),
    ("pos_vert_abs", mav.ESTIMATOR_POS_VERT_ABS),
)


def _num(msg: Any, name: str) -> float:
    """A numeric field as a float (NaN when absent or not a number)."""
    try:
        return float(getattr(msg, name))
    except (TypeError, ValueError, AttributeError):
        return math.nan


def _stamp_ns(msg: Any, name: str) -> int:
    """``usec``/``time_usec`` (simulated µs since boot) in ns; -1 when unusable."""
    value = getattr(msg, name, None)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        return -1
    return value * 1000


def _cov_ned(cov: Any) -> tuple[float, ...] | None:
    """The 3x3 position block of a MAVLink 21-element upper-triangular 6x6 covariance (row
    major, x y z first), or None when its first element says "unknown" (NaN)."""
    try:
        c = [float(x) for x in cov]
    except (TypeError, ValueError):
        return None
    if len(c) < 12 or math.isnan(c[0]):
        return None
    xx, xy, xz, yy, yz, zz = c[0], c[1], c[2], c[6], c[7], c[11]
    return (xx, xy, xz, xy, yy, yz, xz, yz, zz)


class NavLink:
    """Decodes aids (I/O thread), feeds them to the filter (simulation thread), and serves the
    estimate's telemetry. Also a Sink: it polls the filter's events for STATUSTEXT."""

    def __init__(self, endpoint: EndpointLike, *, aid: bool) -> None:
        self.ep = endpoint
        self.aid = aid
        self.nav: OnboardNav | None = None
        self.params: ParamStore | None = None
        self.received = 0
        self.ignored = 0  # EV messages while EKF2_EV_CTRL bit 0 is off
        self._next_event_ns = 0
        # (the sample, its estimated twin): the sample is held, so its identity is not reused
        self._sample_cache: tuple[SimSample, SimSample] | None = None

    def attach(self, nav: OnboardNav, params: ParamStore) -> None:
        """Connect to the flight's filter and parameters; register handlers and streams."""
        self.nav = nav
        self.params = params
        nav.status_wanted = True  # ESTIMATOR_STATUS reads nav.last_status
        nav.gnss_enabled = lambda: int(params.get("EKF2_GPS_CTRL")) & 1 == 1
        if self.aid:
            for name in ("VISION_POSITION_ESTIMATE", "ODOMETRY", "GPS_INPUT"):
                self.ep.register(name, self._on_aid)
            self.ep.register("GLOBAL_POSITION_SENSOR", self._on_aid)
        streams = self.ep.streams
        home = self.ep.home
        rates = tm.DEFAULT_RATES_HZ
        for msg_id, build in (
            (mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, lambda s: tm.global_position_int(s, home)),
            (mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED, tm.local_position_ned),
            (mav.MAVLINK_MSG_ID_ATTITUDE, tm.attitude),
            (mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, tm.attitude_quaternion),
            (mav.MAVLINK_MSG_ID_VFR_HUD, tm.vfr_hud),
        ):
            streams.add(msg_id, self._from_estimate(build), rates.get(msg_id, 0.0))
        streams.add(
            mav.MAVLINK_MSG_ID_GPS_RAW_INT,
            self._gps_raw_int,
            rates.get(mav.MAVLINK_MSG_ID_GPS_RAW_INT, 0.0),
        )
        streams.add(
            mav.MAVLINK_MSG_ID_ESTIMATOR_STATUS, self._estimator_status, ESTIMATOR_STATUS_HZ
        )

    # ------------------------------------------------------------------ telemetry (I/O thread)

    def _from_estimate(self, build: Callable[[SimSample], Message]) -> Builder:
        """A stream builder of ``build`` fed the estimate instead of the truth."""

        def builder(sample: SimSample | None, _fix: GpsFix | None) -> Message | None:
            return None if sample is None else build(self._estimated(sample))

        return builder

    def _estimated(self, sample: SimSample) -> SimSample:
        """``sample`` with the estimate as its state (the truth until the filter has one)."""
        est = sample.nav
        if est is None:
            return sample
        cache = self._sample_cache
        if cache is not None and cache[0] is sample:
            return cache[1]
        state = estimated_state(
            est,
            sample.imu,
            airspeed_m_s=sample.state.airspeed_m_s,
            on_ground=sample.state.on_ground,
            home_alt_amsl_m=self.ep.home.alt_amsl_m,
        )
        out = replace(sample, state=state)
        self._sample_cache = (sample, out)
        return out

    def _gps_raw_int(self, sample: SimSample | None, fix: GpsFix | None) -> Message | None:
        if sample is None:
            return None
        t = sample.state.sim_time_ns
        if fix is None or t - fix.sim_time_ns > NO_FIX_AFTER_NS:
            none = GpsFix(
                sim_time_ns=t, lat_deg=0.0, lon_deg=0.0, alt_amsl_m=0.0,
                vel_ned_m_s=(0.0, 0.0, 0.0), fix_type=0, satellites=0, eph_m=99.99, epv_m=99.99,
            )  # fmt: skip
            return tm.gps_raw_int(sample, none)
        return tm.gps_raw_int(sample, fix)

    def _estimator_status(self, sample: SimSample | None, _fix: GpsFix | None) -> Message | None:
        nav = self.nav
        status = None if nav is None else nav.last_status
        if sample is None or status is None:
            return None
        flags = 0
        for name, bit in _FLAG_BITS:
            if getattr(status.flags, name):
                flags |= bit
        if status.flags.dead_reckoning:
            flags |= mav.ESTIMATOR_PRED_POS_HORIZ_REL

        def ratio(x: float) -> float:
            return float(x) if math.isfinite(x) else 0.0

        return mav.MAVLink_estimator_status_message(
            sample.state.sim_time_ns // 1000,
            flags,
            ratio(status.vel_ratio),
            ratio(status.pos_horiz_ratio),
            ratio(status.pos_vert_ratio),
            ratio(status.mag_ratio),
            0.0,
            ratio(status.tas_ratio),
            ratio(status.pos_horiz_accuracy_m),
            ratio(status.pos_vert_accuracy_m),
        )

    # ------------------------------------------------------------------ aids (I/O thread)

    def _on_aid(self, _ch: Channel, msg: Message) -> None:
        self.received += 1
        m = self.decode(msg)
        if m is None:
            return
        nav = self.nav
        if nav is None:
            return

        def fuse(_ap: object) -> None:
            nav.fuse_aid(m, nav.now_ns)

        self.ep.post(fuse)

    def _param(self, name: str, default: float) -> float:
        params = self.params
        if params is None:
            return default
        try:
            return params.get(name)
        except Exception:  # a store without the parameter
            return default

    def decode(self, msg: Any) -> AidMeasurement | None:
        """The aid measurement of one message; None when it is not to be fused (EV off)."""
        kind = msg.get_type()
        sigma = self._param("EKF2_EVP_NOISE", 5.0)
        if kind in ("VISION_POSITION_ESTIMATE", "ODOMETRY"):
            if int(self._param("EKF2_EV_CTRL", 0.0)) & 1 == 0:
                self.ignored += 1
                return None
            if kind == "ODOMETRY":
                stamp = _stamp_ns(msg, "time_usec")
                frame_id = getattr(msg, "frame_id", -1)
                if frame_id == mav.MAV_FRAME_LOCAL_NED:
                    frame = AidFrame.NED.value
                elif frame_id == mav.MAV_FRAME_LOCAL_ENU:
                    frame = AidFrame.ENU.value
                else:
                    frame = f"mav_frame_{frame_id}"
                cov_src = getattr(msg, "pose_covariance", None)
            else:
                stamp = _stamp_ns(msg, "usec")
                frame = AidFrame.NED.value
                cov_src = getattr(msg, "covariance", None)
            position = (_num(msg, "x"), _num(msg, "y"), _num(msg, "z"))
            cov = None
            if int(self._param("EKF2_EV_NOISE_MD", 0.0)) == 0:
                cov = _cov_ned(cov_src)
                if cov is not None and frame == AidFrame.ENU.value:
                    # ENU axes: swap x/y of the NED-ordered block (the covariance is symmetric).
                    cov = (cov[4], cov[3], cov[5], cov[1], cov[0], cov[2], cov[7], cov[6], cov[8])
            return AidMeasurement(
                name=EV_AID, sim_time_ns=stamp, position=position, frame=frame, cov_m2=cov,
                sigma_m=None if cov is not None else sigma,
            )  # fmt: skip
        if kind == "GPS_INPUT":
            stamp = _stamp_ns(msg, "time_usec")
            if getattr(msg, "fix_type", 0) < 2:
                return AidMeasurement(name=GLOBAL_AID, sim_time_ns=stamp, position=None)
            acc = _num(msg, "horiz_accuracy")
            ignored = (
                getattr(msg, "ignore_flags", 0) & mav.GPS_INPUT_IGNORE_FLAG_HORIZONTAL_ACCURACY
            )
            position = (_num(msg, "lat") * 1e-7, _num(msg, "lon") * 1e-7, _num(msg, "alt"))
        else:  # GLOBAL_POSITION_SENSOR
            stamp = _stamp_ns(msg, "time_usec")
            acc = _num(msg, "eph")
            ignored = 0
            position = (_num(msg, "lat") * 1e-7, _num(msg, "lon") * 1e-7, _num(msg, "alt"))
        use = not ignored and math.isfinite(acc) and acc > 0.0
        return AidMeasurement(
            name=GLOBAL_AID, sim_time_ns=stamp, position=position, frame=AidFrame.WGS84.value,
            sigma_m=acc if use else sigma,
        )  # fmt: skip

    # ------------------------------------------------------------------ Sink (simulation thread)

    def on_sample(self, sample: SimSample) -> None:
        """Every 50 ms: the filter's events as STATUSTEXT."""
        t = sample.state.sim_time_ns
        if t < self._next_event_ns or self.nav is None:
            return
        self._next_event_ns = t + EVENT_PERIOD_NS
        for severity, text in self.nav.pop_events():
            self.ep.text(severity, text)

    def on_frame(self, frame: CameraFrame) -> None:
        """Frames are not for MAVLink."""

    def close(self, result: FlightResult) -> None:
        """Nothing to close."""
