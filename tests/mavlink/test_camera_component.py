"""The camera component (MAV_COMP_ID_CAMERA = 100): its own HEARTBEAT and the real camera's
CAMERA_INFORMATION (--camera-width/--camera-height/--camera-hfov-deg), as on a PX4 vehicle."""

from __future__ import annotations

import math

import pytest
from gcs import Gcs, serve
from pymavlink.dialects.v20 import common as mavlink2

M = mavlink2
pytestmark = pytest.mark.integration


def test_the_camera_component_reports_the_served_camera() -> None:
    args = ("--camera-width", "320", "--camera-height", "240", "--camera-hfov-deg", "70")
    with serve("--mavlink", "udpin:127.0.0.1:0", *args) as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        hb = gcs.recv(["HEARTBEAT"])
        while hb.get_srcComponent() != M.MAV_COMP_ID_CAMERA:
            hb = gcs.recv(["HEARTBEAT"])
        assert (hb.get_srcSystem(), hb.type) == (1, M.MAV_TYPE_CAMERA)
        assert hb.autopilot == M.MAV_AUTOPILOT_INVALID
        info_id = M.MAVLINK_MSG_ID_CAMERA_INFORMATION
        cam = M.MAV_COMP_ID_CAMERA
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, info_id, component=cam) == (
            M.MAV_RESULT_ACCEPTED
        )
        info = gcs.recv(["CAMERA_INFORMATION"])
        assert info.get_srcComponent() == cam
        assert (info.resolution_h, info.resolution_v) == (320, 240)
        hfov = math.degrees(2 * math.atan(info.sensor_size_h / 2 / info.focal_length))
        assert hfov == pytest.approx(70.0, abs=0.01)
        assert info.sensor_size_v / info.sensor_size_h == pytest.approx(240 / 320)
        assert info.flags & M.CAMERA_CAP_FLAGS_CAPTURE_IMAGE
        # The camera's capture commands, answered by the camera; others are unsupported.
        assert gcs.command(M.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.02, component=cam) == (
            M.MAV_RESULT_ACCEPTED
        )
        assert gcs.command(M.MAV_CMD_IMAGE_STOP_CAPTURE, component=cam) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_SET_CAMERA_ZOOM, 0, 2, component=cam) == (
            M.MAV_RESULT_UNSUPPORTED
        )
        # The autopilot proxies no camera: it does not answer for component 100 (MAVSDK would
        # list it as a second camera), by the new request nor by the legacy one.
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, info_id) == M.MAV_RESULT_UNSUPPORTED
        assert gcs.command(M.MAV_CMD_REQUEST_CAMERA_INFORMATION, 1) == M.MAV_RESULT_UNSUPPORTED
        gcs.close()
