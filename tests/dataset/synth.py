"""A scripted flight for the dataset tests: real VehicleStates computed with air_sitl.frames.

The aircraft flies east at 15 m/s and 200 m above home, banks in a slow sine and yaws a little,
so every frame has a different, exactly known pose. Frames are small real JPEGs.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import cv2
import numpy as np
from vehicle_states import airborne_state

from air_sitl.clock import CAMERA_PERIOD_NS, PHYSICS_STEP_NS
from air_sitl.frames import euler2quat, ned2geodetic
from air_sitl.sinks import FlightResult, Sink
from air_sitl.state import (
    AutopilotStatus,
    CameraFrame,
    FlightMode,
    GeoPoint,
    GpsFix,
    ImuSample,
    SimSample,
)

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
CAPTURE_START_NS = 2_000_000_000
W, H = 160, 120


def sample_at(t_ns: int, frames: int) -> SimSample:
    """The physics sample at ``t_ns``; capture runs for ``frames`` frames from 2 s."""
    s = t_ns / 1e9
    north, east, down = 20.0 + 0.5 * s, 15.0 * s, -200.0 - 0.1 * s
    roll = math.radians(10.0) * math.sin(0.3 * s)
    pitch = math.radians(2.0)
    yaw = math.radians(80.0) + 0.01 * s
    lat, lon, alt = ned2geodetic(north, east, down, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    state = airborne_state(
        t_ns,
        lat_deg=lat,
        lon_deg=lon,
        alt_amsl_m=alt,
        alt_agl_m=alt - HOME.alt_amsl_m,
        pos_ned_m=(north, east, down),
        rpy_rad=(roll, pitch, yaw),
        vel_ned_m_s=(0.5, 15.0, -0.1),
        rate_frd_rad_s=(0.003 * math.cos(0.3 * s), 0.0, 0.01),
        specific_force_frd_m_s2=(0.1, 0.0, -9.81),
        airspeed_m_s=15.2,
    )
    end = CAPTURE_START_NS + frames * CAMERA_PERIOD_NS
    capturing = CAPTURE_START_NS <= t_ns < end
    status = AutopilotStatus(
        mode=FlightMode.MISSION,
        armed=True,
        current_seq=2 if capturing else 1,
        capturing=capturing,
        mission_completed=t_ns >= end + 1_000_000_000,
    )
    k = t_ns // PHYSICS_STEP_NS
    imu = ImuSample(
        sim_time_ns=t_ns,
        gyro_frd_rad_s=(0.001 * (k % 7), -0.002, 0.01),
        accel_frd_m_s2=(0.1, 0.01 * (k % 3), -9.8),
        q_ahrs_body_to_ned_wxyz=euler2quat(roll + 0.001, pitch, yaw - 0.002),
    )
    gps = None
    if t_ns % 200_000_000 == 0:
        gps = GpsFix(
            sim_time_ns=t_ns,
            lat_deg=lat + 1e-6,
            lon_deg=lon,
            alt_amsl_m=alt + 0.5,
            vel_ned_m_s=(0.5, 15.0, -0.1),
            fix_type=3,
            satellites=14,
            eph_m=1.5,
            epv_m=3.0,
        )
    return SimSample(state=state, autopilot=status, imu=imu, gps=gps)


def jpeg_of(index: int) -> bytes:
    """A small real JPEG, different for every frame."""
    rng = np.random.default_rng(index)
    img = rng.integers(0, 255, (H, W, 3), dtype=np.uint8)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 80])
    assert ok
    return bytes(buf)


def map_xy(sample: SimSample) -> tuple[int, int]:
    """A stand-in map pixel (1 px per metre, origin 5000 px west/north of home)."""
    n, e, _ = sample.state.pos_ned_m
    return (round(5000 + e), round(5000 - n))


def samples(frames: int) -> Iterator[tuple[SimSample, CameraFrame | None]]:
    """Every physics sample of the scripted flight, with its frame when one is taken."""
    end = CAPTURE_START_NS + frames * CAMERA_PERIOD_NS + 1_000_000_000
    t = 0
    index = 0
    while t <= end:
        sample = sample_at(t, frames)
        frame = None
        if sample.autopilot.capturing and t % CAMERA_PERIOD_NS == 0:
            frame = CameraFrame(
                index=index,
                sim_time_ns=t,
                jpeg=jpeg_of(index),
                width_px=W,
                height_px=H,
                sample=sample,
                map_xy_px=map_xy(sample),
            )
            index += 1
        yield sample, frame
        t += PHYSICS_STEP_NS


def fly(
    sink: Sink, frames: int, *, first_frame: int = 0, stop_after_frame: int | None = None
) -> None:
    """Feed the scripted flight to ``sink`` like the runner does (frames from first_frame)."""
    for sample, frame in samples(frames):
        sink.on_sample(sample)
        if frame is not None and frame.index >= first_frame:
            sink.on_frame(frame)
            if stop_after_frame is not None and frame.index >= stop_after_frame:
                return
    sink.close(FlightResult(mission_completed=True, sim_time_ns=0, wall_time_s=0.0))
