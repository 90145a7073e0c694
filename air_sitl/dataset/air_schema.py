"""The AIR archive contract (SPEC section 1) and the one place where NED/FRD becomes ENU/FLU.

Inside the code positions are NED relative to home and attitudes rotate body FRD to NED
(Hamilton, scalar first). AIR's ``metadata.csv`` follows ROS REP-103 as Gazebo wrote it: ENU
metres relative to home, body FLU to world ENU, quaternions in x, y, z, w order. The conversion
is here, next to the row formatters, and nowhere else.

Files of an archive folder (all names relative to the folder):

- ``metadata.csv``: the 20 AIR columns, one row per frame (``AIR_COLUMNS``);
- ``frames.csv``: per frame everything else worth having (``FRAMES_COLUMNS``);
- ``imu.csv``: raw IMU at the physics rate, body FRD (``IMU_COLUMNS``);
- ``frame_NNNNNN.jpg`` images, ``camera.yaml``, ``<scenario>.plan``, ``trajectory.csv``,
  ``summary.json`` (the one file with wall-clock figures), ``manifest.json`` (written last).
"""

from __future__ import annotations

import math

from air_sitl.frames import (  # the AIR CSV's ROS conventions (SPEC 2), re-exported here
    ned2enu,
    q_frd_ned_to_flu_enu,
    quat2euler,
)
from air_sitl.nav.columns import NAV_COLUMNS, nav_fields
from air_sitl.state import CameraFrame, GpsFix, ImuSample, SimSample, Vec3

AIR_COLUMNS: tuple[str, ...] = (
    "Filename",
    "Latitude",
    "Longitude",
    "RelativeAltitude",
    "ImuX",
    "ImuY",
    "ImuZ",
    "ImuW",
    "PoseX",
    "PoseY",
    "PoseZ",
    "OrientationX",
    "OrientationY",
    "OrientationZ",
    "OrientationW",
    "MapX",
    "MapY",
    "SvoX",
    "SvoY",
    "SvoZ",
)
AIR_HEADER = ",".join(AIR_COLUMNS) + "\n"

FRAMES_COLUMNS: tuple[str, ...] = (
    "frame",
    "sim_time_ns",
    "filename",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "alt_rel_m",
    "east_m",
    "north_m",
    "up_m",
    "ned_north_m",
    "ned_east_m",
    "ned_down_m",
    "q_ned_w",
    "q_ned_x",
    "q_ned_y",
    "q_ned_z",
    "roll_deg",
    "pitch_deg",
    "yaw_deg",
    "vn_m_s",
    "ve_m_s",
    "vd_m_s",
    "airspeed_m_s",
    "p_rad_s",
    "q_rad_s",
    "r_rad_s",
    "fx_m_s2",
    "fy_m_s2",
    "fz_m_s2",
    "gps_time_ns",
    "gps_lat_deg",
    "gps_lon_deg",
    "gps_alt_amsl_m",
    "gps_vn_m_s",
    "gps_ve_m_s",
    "gps_vd_m_s",
    "gps_fix_type",
    "gps_satellites",
    "gps_eph_m",
    "gps_epv_m",
    "map_x_px",
    "map_y_px",
    "mission_seq",
    "mode",
)
FRAMES_HEADER = ",".join(FRAMES_COLUMNS) + "\n"
FRAMES_NAV_COLUMNS = FRAMES_COLUMNS + NAV_COLUMNS
FRAMES_NAV_HEADER = ",".join(FRAMES_NAV_COLUMNS) + "\n"
# With relief (--dem): the height above the surface under the aircraft (terrain, roof, canopy),
# last, so that archives without a DEM keep their columns.
FRAMES_AGL_COLUMNS: tuple[str, ...] = ("agl_m",)


def frames_header(*, nav: bool, agl: bool) -> str:
    """The ``frames.csv`` header: FRAMES_COLUMNS, then NAV_COLUMNS (``--nav ekf``), then
    FRAMES_AGL_COLUMNS (``--dem``)."""
    columns = FRAMES_NAV_COLUMNS if nav else FRAMES_COLUMNS
    return ",".join(columns + (FRAMES_AGL_COLUMNS if agl else ())) + "\n"


# Every header a frames.csv may have (an unfinished archive is recognised by it).
FRAMES_HEADERS = tuple(frames_header(nav=n, agl=a) for n in (False, True) for a in (False, True))

IMU_COLUMNS: tuple[str, ...] = (
    "sim_time_ns",
    "gyro_x_rad_s",
    "gyro_y_rad_s",
    "gyro_z_rad_s",
    "accel_x_m_s2",
    "accel_y_m_s2",
    "accel_z_m_s2",
    "ahrs_qw",
    "ahrs_qx",
    "ahrs_qy",
    "ahrs_qz",
)
IMU_HEADER = ",".join(IMU_COLUMNS) + "\n"

METADATA_CSV = "metadata.csv"
FRAMES_CSV = "frames.csv"
IMU_CSV = "imu.csv"
CAMERA_YAML = "camera.yaml"
SUMMARY_JSON = "summary.json"
MANIFEST_JSON = "manifest.json"
TRAJECTORY_CSV = "trajectory.csv"
RECORDING_JSON = ".air-sitl-recording.json"  # present only while a recording is unfinished
ESTIMATES_DIR = "estimates"
FRAME_PREFIX = "frame_"
FRAME_SUFFIX = ".jpg"
# A GPS fix older than this is reported as "no fix" in frames.csv (denied or lost).
GPS_STALE_NS = 400_000_000


def frame_filename(index: int) -> str:
    """The image file name of frame ``index`` (relative to the archive folder)."""
    return f"{FRAME_PREFIX}{index:06d}{FRAME_SUFFIX}"


def frame_index_of(name: str) -> int | None:
    """Inverse of :func:`frame_filename`; None for any other name."""
    if not (name.startswith(FRAME_PREFIX) and name.endswith(FRAME_SUFFIX)):
        return None
    digits = name[len(FRAME_PREFIX) : -len(FRAME_SUFFIX)]
    return int(digits) if digits.isdigit() else None


def _svo_text(svo_enu_m: Vec3 | None) -> str:
    if svo_enu_m is None:
        return "nan,nan,nan"
    return ",".join("nan" if math.isnan(c) else f"{c:.4f}" for c in svo_enu_m)


def metadata_row(
    filename: str,
    sample: SimSample,
    map_xy_px: tuple[int, int],
    svo_enu_m: Vec3 | None = None,
) -> str:
    """One AIR ``metadata.csv`` line (with its newline) for a frame taken at ``sample``."""
    s = sample.state
    e, n, u = ned2enu(s.pos_ned_m)
    ow, ox, oy, oz = q_frd_ned_to_flu_enu(s.q_body_to_ned_wxyz)
    iw, ix, iy, iz = q_frd_ned_to_flu_enu(sample.imu.q_ahrs_body_to_ned_wxyz)
    return (
        f"{filename},{s.lat_deg:.9f},{s.lon_deg:.9f},{s.alt_agl_m:.4f},"
        f"{ix:.9f},{iy:.9f},{iz:.9f},{iw:.9f},"
        f"{e:.4f},{n:.4f},{u:.4f},"
        f"{ox:.9f},{oy:.9f},{oz:.9f},{ow:.9f},"
        f"{int(map_xy_px[0])},{int(map_xy_px[1])},{_svo_text(svo_enu_m)}\n"
    )


def _gps_text(gps: GpsFix | None, now_ns: int) -> str:
    if gps is None or now_ns - gps.sim_time_ns > GPS_STALE_NS or gps.fix_type == 0:
        return ",nan,nan,nan,nan,nan,nan,0,0,nan,nan"
    vn, ve, vd = gps.vel_ned_m_s
    return (
        f"{gps.sim_time_ns},{gps.lat_deg:.9f},{gps.lon_deg:.9f},{gps.alt_amsl_m:.4f},"
        f"{vn:.4f},{ve:.4f},{vd:.4f},{gps.fix_type},{gps.satellites},"
        f"{gps.eph_m:.3f},{gps.epv_m:.3f}"
    )


def frames_row(
    frame: CameraFrame,
    filename: str,
    last_gps: GpsFix | None,
    *,
    nav: bool = False,
    agl: bool = False,
) -> str:
    """One ``frames.csv`` line: timestamp, truth, GPS as last received, map pixel, mission
    (``nav``: then the NAV_COLUMNS; ``agl``: then the height above the surface)."""
    sample = frame.sample
    s = sample.state
    a = sample.autopilot
    n, e, d = s.pos_ned_m
    qw, qx, qy, qz = s.q_body_to_ned_wxyz
    roll, pitch, yaw = quat2euler(s.q_body_to_ned_wxyz)
    vn, ve, vd = s.vel_ned_m_s
    p, q, r = s.rate_frd_rad_s
    fx, fy, fz = s.specific_force_frd_m_s2
    return (
        f"{frame.index},{frame.sim_time_ns},{filename},"
        f"{s.lat_deg:.9f},{s.lon_deg:.9f},{s.alt_amsl_m:.4f},{s.alt_agl_m:.4f},"
        f"{e:.4f},{n:.4f},{-d:.4f},{n:.4f},{e:.4f},{d:.4f},"
        f"{qw:.9f},{qx:.9f},{qy:.9f},{qz:.9f},"
        f"{math.degrees(roll):.5f},{math.degrees(pitch):.5f},{math.degrees(yaw):.5f},"
        f"{vn:.4f},{ve:.4f},{vd:.4f},{s.airspeed_m_s:.4f},"
        f"{p:.6f},{q:.6f},{r:.6f},{fx:.5f},{fy:.5f},{fz:.5f},"
        f"{_gps_text(last_gps, s.sim_time_ns)},"
        f"{int(frame.map_xy_px[0])},{int(frame.map_xy_px[1])},{a.current_seq},{a.mode.value}"
        + ("" if not nav else f",{nav_fields(sample.nav)}")
        + ("\n" if not agl else f",{s.surface_agl_m:.4f}\n")
    )


def imu_row(imu: ImuSample) -> str:
    """One ``imu.csv`` line: gyro and accelerometer in body FRD, AHRS quaternion body->NED."""
    gx, gy, gz = imu.gyro_frd_rad_s
    ax, ay, az = imu.accel_frd_m_s2
    qw, qx, qy, qz = imu.q_ahrs_body_to_ned_wxyz
    return (
        f"{imu.sim_time_ns},{gx:.7f},{gy:.7f},{gz:.7f},{ax:.6f},{ay:.6f},{az:.6f},"
        f"{qw:.9f},{qx:.9f},{qy:.9f},{qz:.9f}\n"
    )
