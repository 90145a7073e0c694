"""Telemetry messages of a PX4 fixed-wing built from the vehicle's truth (a SimSample).

Scaled integers (degE7, mm, cm/s, cdeg) appear here and in the codec only. Position and
attitude come from ``sample.state``; GPS_RAW_INT uses the last GNSS fix when there is one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from air_sitl.mavlink.codec import Message, mav
from air_sitl.state import BatteryState, FlightMode, GeoPoint, GpsFix, SimSample

# PX4 custom modes: custom_mode = main << 16 | sub << 24.
PX4_MAIN_AUTO = 4
PX4_AUTO_READY, PX4_AUTO_TAKEOFF, PX4_AUTO_LOITER, PX4_AUTO_MISSION = 1, 2, 3, 4
PX4_AUTO_RTL, PX4_AUTO_LAND = 5, 6
MODE_TO_PX4: dict[FlightMode, tuple[int, int]] = {
    FlightMode.IDLE: (PX4_MAIN_AUTO, PX4_AUTO_LOITER),  # PX4 shows "Hold" on the ground
    FlightMode.TAKEOFF: (PX4_MAIN_AUTO, PX4_AUTO_TAKEOFF),
    FlightMode.MISSION: (PX4_MAIN_AUTO, PX4_AUTO_MISSION),
    FlightMode.LOITER: (PX4_MAIN_AUTO, PX4_AUTO_LOITER),
    FlightMode.RTL: (PX4_MAIN_AUTO, PX4_AUTO_RTL),
    FlightMode.LAND: (PX4_MAIN_AUTO, PX4_AUTO_LAND),
}
PX4_TO_MODE: dict[tuple[int, int], FlightMode] = {
    (PX4_MAIN_AUTO, PX4_AUTO_TAKEOFF): FlightMode.TAKEOFF,
    (PX4_MAIN_AUTO, PX4_AUTO_MISSION): FlightMode.MISSION,
    (PX4_MAIN_AUTO, PX4_AUTO_LOITER): FlightMode.LOITER,
    (PX4_MAIN_AUTO, PX4_AUTO_RTL): FlightMode.RTL,
    (PX4_MAIN_AUTO, PX4_AUTO_LAND): FlightMode.LAND,
}

# PX4's version 1.14.0, released: what clients use to pick PX4 behaviour.
FLIGHT_SW_VERSION = (1 << 24) | (14 << 16) | (0 << 8) | 255
CAPABILITIES = (
    mav.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | mav.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mav.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mav.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | mav.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
)
SENSORS = (
    mav.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mav.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mav.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mav.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mav.MAV_SYS_STATUS_SENSOR_DIFFERENTIAL_PRESSURE
    | mav.MAV_SYS_STATUS_SENSOR_GPS
    | mav.MAV_SYS_STATUS_SENSOR_ANGULAR_RATE_CONTROL
    | mav.MAV_SYS_STATUS_SENSOR_ATTITUDE_STABILIZATION
    | mav.MAV_SYS_STATUS_SENSOR_YAW_POSITION
    | mav.MAV_SYS_STATUS_SENSOR_Z_ALTITUDE_CONTROL
    | mav.MAV_SYS_STATUS_SENSOR_XY_POSITION_CONTROL
    | mav.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mav.MAV_SYS_STATUS_AHRS
    | mav.MAV_SYS_STATUS_PREARM_CHECK
)
# Default stream rates in simulated Hz (PX4's normal-mode rates, roughly).
DEFAULT_RATES_HZ: dict[int, float] = {
    mav.MAVLINK_MSG_ID_SYS_STATUS: 1.0,
    mav.MAVLINK_MSG_ID_GPS_RAW_INT: 5.0,
    mav.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
    mav.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 10.0,
    mav.MAVLINK_MSG_ID_ATTITUDE: 20.0,
    mav.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: 20.0,
    mav.MAVLINK_MSG_ID_VFR_HUD: 4.0,
    mav.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 1.0,
    mav.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
    mav.MAVLINK_MSG_ID_MISSION_CURRENT: 1.0,
    mav.MAVLINK_MSG_ID_BATTERY_STATUS: 1.0,
}

# MISSION_CURRENT.mission_state
MISSION_STATE_NO_MISSION, MISSION_STATE_NOT_STARTED, MISSION_STATE_ACTIVE = 1, 2, 3
MISSION_STATE_PAUSED, MISSION_STATE_COMPLETE = 4, 5
# Modes a mission passes through (its take-off, its RTL and landing items).
_MISSION_MODES = frozenset(
    {FlightMode.MISSION, FlightMode.TAKEOFF, FlightMode.RTL, FlightMode.LAND}
)


def _clamp_int(value: float, lo: int, hi: int) -> int:
    if not math.isfinite(value):
        return 0
    return max(lo, min(hi, round(value)))


def _cdeg(angle_rad: float) -> int:
    return round(math.degrees(angle_rad) % 360.0 * 100) % 36000


def custom_mode(mode: FlightMode) -> int:
    """PX4 custom_mode of a flight mode."""
    main, sub = MODE_TO_PX4[mode]
    return (main << 16) | (sub << 24)


def heartbeat(mode: FlightMode, armed: bool) -> Message:
    """HEARTBEAT of a PX4 fixed-wing in ``mode``."""
    base = (
        mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        | mav.MAV_MODE_FLAG_AUTO_ENABLED
        | mav.MAV_MODE_FLAG_GUIDED_ENABLED
        | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
    )
    if armed:
        base |= mav.MAV_MODE_FLAG_SAFETY_ARMED
    state = mav.MAV_STATE_ACTIVE if armed else mav.MAV_STATE_STANDBY
    return mav.MAVLink_heartbeat_message(
        mav.MAV_TYPE_FIXED_WING, mav.MAV_AUTOPILOT_PX4, base, custom_mode(mode), state, 3
    )


@dataclass(frozen=True, slots=True, kw_only=True)
class Health:
    """What SYS_STATUS reports besides sensors."""

    prearm_ok: bool = True
    errors_comm: int = 0  # frames dropped by the parsers


def boot_ms(sample: SimSample) -> int:
    """``time_boot_ms``: simulated milliseconds since the vehicle started."""
    return (sample.state.sim_time_ns // 1_000_000) & 0xFFFFFFFF


def sys_status(health: Health, battery: BatteryState | None = None) -> Message:
    """SYS_STATUS with every simulated sensor present, enabled and healthy, and the battery
    (voltage mV, current cA, remaining %; -1 for what is unknown)."""
    healthy = SENSORS if health.prearm_ok else SENSORS & ~mav.MAV_SYS_STATUS_PREARM_CHECK
    volt_mv, current_ca, remaining = (
        (_clamp_int(battery.voltage_v * 1000, 0, 65534),
         _clamp_int(battery.current_a * 100, 0, 32767),
         _clamp_int(battery.remaining * 100, 0, 100))
        if battery is not None else (65535, -1, -1)
    )  # fmt: skip
    return mav.MAVLink_sys_status_message(
        SENSORS, SENSORS, healthy, 100, volt_mv, current_ca, remaining, 0,
        min(health.errors_comm, 65535), 0, 0, 0, 0,
    )  # fmt: skip


def battery_status(battery: BatteryState, cells: int, charge_state: int) -> Message:
    """BATTERY_STATUS of the propulsion pack (cell voltages equal, the pack's in total)."""
    cell_mv = _clamp_int(battery.voltage_v * 1000 / max(cells, 1), 0, 65534)
    voltages = [cell_mv if i < cells else 65535 for i in range(10)]
    return mav.MAVLink_battery_status_message(
        0, mav.MAV_BATTERY_FUNCTION_ALL, mav.MAV_BATTERY_TYPE_LIPO, 32767, voltages,
        _clamp_int(battery.current_a * 100, 0, 32767),
        _clamp_int(battery.consumed_mah, 0, 2**31 - 1),
        _clamp_int(battery.consumed_wh * 36, 0, 2**31 - 1),  # hJ
        _clamp_int(battery.remaining * 100, 0, 100), 0, charge_state, [0, 0, 0, 0], 0, 0,
    )  # fmt: skip


def global_position_int(sample: SimSample, home: GeoPoint) -> Message:
    """GLOBAL_POSITION_INT from the truth state."""
    s = sample.state
    vn, ve, vd = s.vel_ned_m_s
    return mav.MAVLink_global_position_int_message(
        boot_ms(sample),
        _clamp_int(s.lat_deg * 1e7, -(2**31), 2**31 - 1),
        _clamp_int(s.lon_deg * 1e7, -(2**31), 2**31 - 1),
        _clamp_int(s.alt_amsl_m * 1000, -(2**31), 2**31 - 1),
        _clamp_int((s.alt_amsl_m - home.alt_amsl_m) * 1000, -(2**31), 2**31 - 1),
        _clamp_int(vn * 100, -32768, 32767),
        _clamp_int(ve * 100, -32768, 32767),
        _clamp_int(vd * 100, -32768, 32767),
        _cdeg(s.yaw_rad),
    )


def local_position_ned(sample: SimSample) -> Message:
    """LOCAL_POSITION_NED relative to home."""
    s = sample.state
    return mav.MAVLink_local_position_ned_message(boot_ms(sample), *s.pos_ned_m, *s.vel_ned_m_s)


def attitude(sample: SimSample) -> Message:
    """ATTITUDE (Euler angles and body rates) from the truth state."""
    s = sample.state
    p, q, r = s.rate_frd_rad_s
    return mav.MAVLink_attitude_message(
        boot_ms(sample), s.roll_rad, s.pitch_rad, s.yaw_rad, p, q, r
    )


def attitude_quaternion(sample: SimSample) -> Message:
    """ATTITUDE_QUATERNION (w, x, y, z body to NED) from the truth state."""
    s = sample.state
    p, q, r = s.rate_frd_rad_s
    return mav.MAVLink_attitude_quaternion_message(
        boot_ms(sample), *s.q_body_to_ned_wxyz, p, q, r, [0.0, 0.0, 0.0, 0.0]
    )


def gps_raw_int(sample: SimSample, fix: GpsFix | None) -> Message:
    """GPS_RAW_INT from the receiver's last fix (the truth until the first fix)."""
    s = sample.state
    if fix is None:
        lat, lon, alt, vel = s.lat_deg, s.lon_deg, s.alt_amsl_m, s.vel_ned_m_s
        t_us, fix_type, sats, eph, epv = s.sim_time_ns // 1000, 3, 12, 0.8, 1.2
    else:
        lat, lon, alt, vel = fix.lat_deg, fix.lon_deg, fix.alt_amsl_m, fix.vel_ned_m_s
        t_us, fix_type, sats = fix.sim_time_ns // 1000, fix.fix_type, fix.satellites
        eph, epv = fix.eph_m, fix.epv_m
    ground = math.hypot(vel[0], vel[1])
    return mav.MAVLink_gps_raw_int_message(
        t_us,
        fix_type,
        _clamp_int(lat * 1e7, -(2**31), 2**31 - 1),
        _clamp_int(lon * 1e7, -(2**31), 2**31 - 1),
        _clamp_int(alt * 1000, -(2**31), 2**31 - 1),
        _clamp_int(eph * 100, 0, 65534),
        _clamp_int(epv * 100, 0, 65534),
        _clamp_int(ground * 100, 0, 65534),
        _cdeg(math.atan2(vel[1], vel[0])) if ground > 0.5 else 65535,
        sats,
    )


def vfr_hud(sample: SimSample) -> Message:
    """VFR_HUD: airspeed, ground speed, heading, throttle flown (%), AMSL altitude, climb."""
    s = sample.state
    vn, ve, vd = s.vel_ned_m_s
    heading = round(math.degrees(s.yaw_rad)) % 360
    act = sample.actuators
    throttle = _clamp_int(act.throttle * 100, 0, 100) if act is not None else 0
    return mav.MAVLink_vfr_hud_message(
        s.airspeed_m_s, math.hypot(vn, ve), heading, throttle, s.alt_amsl_m, -vd
    )


def extended_sys_state(sample: SimSample) -> Message:
    """EXTENDED_SYS_STATE: landed state."""
    st, ap = sample.state, sample.autopilot
    if st.on_ground:
        landed = mav.MAV_LANDED_STATE_TAKEOFF if ap.mode is FlightMode.TAKEOFF and ap.armed else (
            mav.MAV_LANDED_STATE_ON_GROUND
        )  # fmt: skip
    elif ap.mode is FlightMode.TAKEOFF:
        landed = mav.MAV_LANDED_STATE_TAKEOFF
    elif ap.mode is FlightMode.LAND:
        landed = mav.MAV_LANDED_STATE_LANDING
    else:
        landed = mav.MAV_LANDED_STATE_IN_AIR
    return mav.MAVLink_extended_sys_state_message(mav.MAV_VTOL_STATE_UNDEFINED, landed)


def home_position(home: GeoPoint, sim_time_ns: int) -> Message:
    """HOME_POSITION at the local origin."""
    return mav.MAVLink_home_position_message(
        round(home.lat_deg * 1e7), round(home.lon_deg * 1e7), round(home.alt_amsl_m * 1000),
        0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, sim_time_ns // 1000,
    )  # fmt: skip


def mission_state(sample: SimSample | None, total: int) -> int:
    """MISSION_CURRENT.mission_state: COMPLETE from the last item on, whatever the mode (RTL,
    landing, disarmed), until the mission is uploaded or started again."""
    if total == 0:
        return MISSION_STATE_NO_MISSION
    if sample is None:
        return MISSION_STATE_NOT_STARTED
    ap = sample.autopilot
    if ap.mission_completed:
        return MISSION_STATE_COMPLETE
    if ap.armed and ap.mode in _MISSION_MODES:
        return MISSION_STATE_ACTIVE
    if ap.current_seq > 0:
        return MISSION_STATE_PAUSED
    return MISSION_STATE_NOT_STARTED


def mission_current(sample: SimSample | None, total: int) -> Message:
    """MISSION_CURRENT with the mission state PX4 reports."""
    seq = max(sample.autopilot.current_seq, 0) if sample is not None else 0
    # common.xml: total is UINT16_MAX when the vehicle has no mission (0 means "not supported").
    count = min(total, 65535) if total > 0 else 65535
    state = mission_state(sample, total)
    return mav.MAVLink_mission_current_message(min(seq, 65535), count, state, 0)


def autopilot_version() -> Message:
    """AUTOPILOT_VERSION with the MISSION_INT capability MAVSDK requires."""
    return mav.MAVLink_autopilot_version_message(
        CAPABILITIES, FLIGHT_SW_VERSION, 0, 0, 0,
        [0] * 8, [0] * 8, [0] * 8, 0, 0, 0x41495253, [0] * 18,
    )  # fmt: skip


def _padded(text: bytes, size: int = 32) -> list[int]:
    return list(text[:size].ljust(size, b"\0"))


@dataclass(frozen=True, slots=True, kw_only=True)
class CameraInfo:
    """What CAMERA_INFORMATION says about the simulated camera (``--camera-*`` options)."""

    width_px: int = 640
    height_px: int = 480
    hfov_deg: float = 57.0
    pixel_um: float = 10.0  # a nominal sensor: focal length and sensor size follow from it


def camera_information(
    sim_time_ns: int, camera: CameraInfo | None = None, *, video: bool = False
) -> Message:
    """CAMERA_INFORMATION of the nadir camera: its resolution and a sensor/focal length pair
    that gives its horizontal field of view (square pixels); with ``video`` the flag that
    sends QGroundControl and MAVSDK on to VIDEO_STREAM_INFORMATION."""
    cam = camera or CameraInfo()
    flags = mav.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
    if video:
        flags |= mav.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
    sensor_w_mm = cam.width_px * cam.pixel_um / 1000
    focal_mm = (sensor_w_mm / 2) / math.tan(math.radians(cam.hfov_deg) / 2)
    return mav.MAVLink_camera_information_message(
        sim_time_ns // 1_000_000, _padded(b"air-sitl"), _padded(b"nadir camera"), 0, focal_mm,
        sensor_w_mm, sensor_w_mm * cam.height_px / cam.width_px, cam.width_px, cam.height_px, 0,
        flags, 0, b"", 0, 0,
    )  # fmt: skip


VIDEO_STREAM_ID = 1  # the camera's one stream
VIDEO_STREAM_NAME = b"downward camera"


@dataclass(frozen=True, slots=True, kw_only=True)
class VideoStreamInfo:
    """What VIDEO_STREAM_INFORMATION and VIDEO_STREAM_STATUS say of the stream now."""

    running: bool
    fps: float
    bitrate_bps: int
    uri: str  # as QGroundControl opens it: udp://0.0.0.0:PORT


def video_stream_information(camera: CameraInfo, video: VideoStreamInfo) -> Message:
    """VIDEO_STREAM_INFORMATION of stream 1 of 1: RTP/UDP H.264, as PX4 SITL's stream."""
    flags = mav.VIDEO_STREAM_STATUS_FLAGS_RUNNING if video.running else 0
    return mav.MAVLink_video_stream_information_message(
        VIDEO_STREAM_ID, 1, mav.VIDEO_STREAM_TYPE_RTPUDP, flags, video.fps, camera.width_px,
        camera.height_px, min(video.bitrate_bps, 0xFFFFFFFF), 0, round(camera.hfov_deg),
        VIDEO_STREAM_NAME, video.uri.encode("ascii")[:160], mav.VIDEO_STREAM_ENCODING_H264, 0,
    )  # fmt: skip


def video_stream_status(camera: CameraInfo, video: VideoStreamInfo) -> Message:
    """VIDEO_STREAM_STATUS of stream 1: running or not, and what it sends."""
    flags = mav.VIDEO_STREAM_STATUS_FLAGS_RUNNING if video.running else 0
    return mav.MAVLink_video_stream_status_message(
        VIDEO_STREAM_ID, flags, video.fps, camera.width_px, camera.height_px,
        min(video.bitrate_bps, 0xFFFFFFFF), 0, round(camera.hfov_deg), 0,
    )  # fmt: skip


def camera_settings(sim_time_ns: int, mode_id: int) -> Message:
    """CAMERA_SETTINGS: the mode (image or video), no zoom or focus (NaN: not supported)."""
    nan = float("nan")
    return mav.MAVLink_camera_settings_message(sim_time_ns // 1_000_000, mode_id, nan, nan, 0)


def camera_capture_status(sim_time_ns: int, *, capturing: bool, images: int) -> Message:
    """CAMERA_CAPTURE_STATUS: interval capture at the camera's 50 Hz inside the capture window
    (image_status 3), idle outside (0); no video recording; ``images`` taken so far."""
    status, interval = (3, 0.02) if capturing else (0, 0.0)
    return mav.MAVLink_camera_capture_status_message(
        sim_time_ns // 1_000_000, status, 0, interval, 0, float("nan"), images, 0
    )


def camera_heartbeat() -> Message:
    """HEARTBEAT of the camera component (MAV_COMP_ID_CAMERA), as a PX4 vehicle's camera."""
    return mav.MAVLink_heartbeat_message(
        mav.MAV_TYPE_CAMERA, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE, 3
    )


STATUSTEXT_CHUNK = 50  # characters (bytes) of text in one STATUSTEXT


def statustext(severity: int, text: str, text_id: int = 0) -> list[Message]:
    """STATUSTEXT of ``text``: one message when it fits in 50 bytes, else MAVLink 2 chunks.

    Chunks share a non-zero ``id`` (``text_id``) and count ``chunk_seq`` from 0; a receiver
    knows the last chunk by the NUL in its text, so a text of an exact multiple of 50 bytes
    ends with an empty chunk (common.xml, STATUSTEXT).
    """
    data = text.encode("utf-8")
    if len(data) <= STATUSTEXT_CHUNK:
        return [mav.MAVLink_statustext_message(severity, data, 0, 0)]
    if not 0 < text_id <= 0xFFFF:
        msg = f"STATUSTEXT of {len(data)} bytes needs chunks with an id in 1..65535, got {text_id}"
        raise ValueError(msg)
    chunks = [data[i : i + STATUSTEXT_CHUNK] for i in range(0, len(data), STATUSTEXT_CHUNK)]
    if len(chunks[-1]) == STATUSTEXT_CHUNK:
        chunks.append(b"")
    return [
        mav.MAVLink_statustext_message(severity, chunk, text_id, seq & 0xFF)
        for seq, chunk in enumerate(chunks)
    ]
