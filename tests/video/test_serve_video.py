"""``air-sitl serve`` with its video: what QGroundControl and MAVSDK do with a camera (the
MAVLink video protocol on component 100, then the stream from the URI it gives), started and
stopped by command, off with --no-video, and two vehicles side by side (--instance)."""

from __future__ import annotations

import asyncio
import itertools
import math
import socket
import time
from pathlib import Path

import numpy as np
import pytest
from mavlink.gcs import PX4_MISSION, serve
from mavlink.mavsdk_wait import ground_station
from mavsdk.asyncio.plugins.camera import CameraAsync
from mavsdk.asyncio.plugins.telemetry import TelemetryAsync
from ports import free_port
from qgc import CAMERA, M, QgcLike
from viewers import gst_viewer

from air_sitl.frames import ned2geodetic
from air_sitl.mission.items import MavCmd, MissionItem
from air_sitl.state import GeoPoint

pytestmark = pytest.mark.integration
SMALL = ("--camera-width", "320", "--camera-height", "240")
STREAM_INFO, STREAM_STATUS = "VIDEO_STREAM_INFORMATION", "VIDEO_STREAM_STATUS"
REQUEST = M.MAV_CMD_REQUEST_MESSAGE


def udp_port() -> int:
    return free_port(socket.SOCK_DGRAM)


def port_pair() -> int:
    """A UDP port whose next port is free too (instances 0 and 1), both taken from this
    worker's range so that no later pick lands on the second."""
    for _ in range(100):
        port = udp_port()
        if udp_port() == port + 1:
            return port
    raise AssertionError("no two free ports in a row")


def wait_frames(viewer: object, count: int, timeout_s: float = 90.0) -> None:
    deadline = time.monotonic() + timeout_s
    while viewer.frames() < count:  # type: ignore[attr-defined]
        assert time.monotonic() < deadline, "".join(viewer.output)  # type: ignore[attr-defined]
        time.sleep(0.05)


def silent_for(sock: socket.socket, seconds: float) -> bool:
    """Nothing arrives on ``sock`` for ``seconds``."""
    sock.settimeout(seconds)
    try:
        sock.recv(65536)
    except TimeoutError:
        return True
    return False


def test_qgc_discovers_the_stream_decodes_its_uri_and_starts_and_stops_it(tmp_path: Path) -> None:
    video = udp_port()
    with serve("--mavlink", "udpin:127.0.0.1:0", "--video", f"udp://127.0.0.1:{video}",
               *SMALL) as served:  # fmt: skip
        gcs = QgcLike(f"udpout:127.0.0.1:{served.ports[0]}")
        try:
            # QGC: a HEARTBEAT of component 100 of the vehicle's system is a camera.
            gcs.wait_heard({(1, 1), (1, CAMERA)})
            info = gcs.request(1, CAMERA, REQUEST, "CAMERA_INFORMATION", 259)
            # ... followed by the stream's description, unasked (MAVSDK asks every 20 s only).
            streams = [gcs.recv([STREAM_INFO], 1, CAMERA, 10.0)]
            assert streams[0] is not None, "CAMERA_INFORMATION came alone"
            legacy = gcs.request(1, CAMERA, M.MAV_CMD_REQUEST_CAMERA_INFORMATION,
                                 "CAMERA_INFORMATION", 1)  # fmt: skip
            assert info.flags & M.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
            assert legacy.flags == info.flags
            # Stream 0 is all streams; so is a stream id left unset (NaN: MAVSDK's requests).
            streams += [gcs.request(1, CAMERA, REQUEST, STREAM_INFO, 269, sid)
                        for sid in (0, 1, math.nan)]  # fmt: skip
            streams.append(
                gcs.request(1, CAMERA, M.MAV_CMD_REQUEST_VIDEO_STREAM_INFORMATION, STREAM_INFO, 0)
            )
            for s in streams:
                assert (s.stream_id, s.count, s.type) == (1, 1, M.VIDEO_STREAM_TYPE_RTPUDP)
                assert s.flags & M.VIDEO_STREAM_STATUS_FLAGS_RUNNING
                assert (s.resolution_h, s.resolution_v, s.hfov) == (320, 240, 57)
                assert s.framerate == pytest.approx(30.0) and s.bitrate == 6_000_000
                assert s.uri == f"udp://0.0.0.0:{video}" and s.name
            status = gcs.request(1, CAMERA, REQUEST, STREAM_STATUS, 270, 1)
            assert status.flags & M.VIDEO_STREAM_STATUS_FLAGS_RUNNING
            unset = gcs.request(1, CAMERA, REQUEST, STREAM_STATUS, 270, math.nan)
            assert unset.flags == status.flags
            old = gcs.request(1, CAMERA, M.MAV_CMD_REQUEST_VIDEO_STREAM_STATUS, STREAM_STATUS, 1)
            assert old.flags == status.flags
            assert gcs.command(1, CAMERA, REQUEST, 269, 2) == M.MAV_RESULT_DENIED  # no stream 2
            settings = gcs.request(1, CAMERA, REQUEST, "CAMERA_SETTINGS", 260)
            assert settings.mode_id == M.CAMERA_MODE_IMAGE
            capture = gcs.request(1, CAMERA, M.MAV_CMD_REQUEST_CAMERA_CAPTURE_STATUS,
                                  "CAMERA_CAPTURE_STATUS", 1)  # fmt: skip
            assert capture.image_status == 0 and capture.video_status == 0  # on the ground

            # The URI QGC opens, decoded with QGC's pipeline.
            port = int(streams[0].uri.rsplit(":", 1)[1])
            with gst_viewer(port, 320, 240, tmp_path) as viewer:
                wait_frames(viewer, 10)
            assert float(viewer.frame(-1).std()) > 0.5  # grass seen from the ground

            rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            rx.bind(("127.0.0.1", port))
            try:
                stop = M.MAV_CMD_VIDEO_STOP_STREAMING
                assert gcs.command(1, CAMERA, stop, 1) == M.MAV_RESULT_ACCEPTED
                status = gcs.request(1, CAMERA, REQUEST, STREAM_STATUS, 270, 1)
                assert not status.flags & M.VIDEO_STREAM_STATUS_FLAGS_RUNNING
                info = gcs.request(1, CAMERA, REQUEST, STREAM_INFO, 269, 0)
                assert not info.flags & M.VIDEO_STREAM_STATUS_FLAGS_RUNNING
                time.sleep(0.5)
                rx.setblocking(False)
                while True:  # what was on its way before the stop
                    try:
                        rx.recv(65536)
                    except BlockingIOError:
                        break
                rx.setblocking(True)
                assert silent_for(rx, 2.0)
                start = M.MAV_CMD_VIDEO_START_STREAMING
                assert gcs.command(1, CAMERA, start, 1) == M.MAV_RESULT_ACCEPTED
                status = gcs.request(1, CAMERA, REQUEST, STREAM_STATUS, 270, 1)
                assert status.flags & M.VIDEO_STREAM_STATUS_FLAGS_RUNNING
                assert not silent_for(rx, 10.0)
            finally:
                rx.close()
        finally:
            gcs.close()
        code, out = served.stop()
    assert code == 0
    assert "air-sitl serve: video:" in out and "dropped" in out


def test_no_video_sends_nothing_and_the_camera_says_it_has_no_stream() -> None:
    base = udp_port()
    rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    rx.bind(("127.0.0.1", base))  # where instance 0's video would go
    try:
        with serve("--mavlink", "udpin:127.0.0.1:0", "--no-video", "--video-base-port",
                   str(base), *SMALL) as served:  # fmt: skip
            gcs = QgcLike(f"udpout:127.0.0.1:{served.ports[0]}")
            try:
                gcs.wait_heard({(1, 1), (1, CAMERA)})
                info = gcs.request(1, CAMERA, REQUEST, "CAMERA_INFORMATION", 259)
                assert not info.flags & M.CAMERA_CAP_FLAGS_HAS_VIDEO_STREAM
                assert gcs.command(1, CAMERA, REQUEST, 269, 0) == M.MAV_RESULT_UNSUPPORTED
                assert silent_for(rx, 3.0)
            finally:
                gcs.close()
            _code, out = served.stop()
        assert "video:" not in out
    finally:
        rx.close()


def test_at_speed_1_the_viewer_gets_the_frame_rate(tmp_path: Path) -> None:
    """At --speed 1, at least 95 % of --video-fps frames a wall-clock second reach QGC's
    pipeline: the median second of 10, once the picture is up (a 320x240 camera: the rate, not
    the machine's spare cores, is what is measured; the median: a second in which the loaded
    machine stalled every process does not decide). The simulation's own pace over the same
    window (time_boot_ms) is the floor: on a machine so loaded that the simulation itself
    falls behind real time, the stream owes 95 % of what that pace allows."""
    video = udp_port()
    seconds = 10  # windows of one wall second each
    with (
        serve("--mavlink", "udpin:127.0.0.1:0", "--video", f"udp://127.0.0.1:{video}",
              *SMALL) as served,
        gst_viewer(video, 320, 240, tmp_path) as viewer,
    ):  # fmt: skip
        gcs = QgcLike(f"udpout:127.0.0.1:{served.ports[0]}")
        try:
            gcs.wait_heard({(1, 1)})
            wait_frames(viewer, 30)
            marks = []
            for second in range(seconds + 1):
                if second in (0, seconds):
                    while gcs.conn.recv_match(blocking=False) is not None:
                        pass  # the backlog: the next ATTITUDE is a fresh one
                    msg = gcs.recv(["ATTITUDE"], 1, 1, 10.0)
                    assert msg is not None
                    sim_s = msg.time_boot_ms / 1e3
                marks.append((time.monotonic(), sim_s, viewer.frames()))
                if second < seconds:
                    time.sleep(max(0.0, marks[0][0] + second + 1 - time.monotonic()))
        finally:
            gcs.close()
    per_second = sorted(
        (n1 - n0) / (w1 - w0) for (w0, _, n0), (w1, _, n1) in itertools.pairwise(marks)
    )
    rate = per_second[len(per_second) // 2]
    pace = (marks[-1][1] - marks[0][1]) / (marks[-1][0] - marks[0][0])
    print(f"--speed 1: median {rate:.1f} frames per wall second of 30 (slowest "
          f"{per_second[0]:.1f}), simulation at {pace:.2f}x")  # fmt: skip
    assert rate >= 0.95 * 30 * min(1.0, pace)


def test_mavsdk_camera_plugin_lists_the_camera_and_its_stream() -> None:
    port, video = udp_port(), udp_port()

    async def check() -> None:
        async with ground_station(port, timeout_s=60) as system:
            camera = CameraAsync(system)

            async def listed() -> list[object]:
                async for found in camera.subscribe_camera_list():
                    if found.cameras:
                        return list(found.cameras)
                raise AssertionError("no camera list")

            async def first_stream() -> object:
                async for update in camera.subscribe_video_stream_info():
                    if update.video_stream_info.settings.uri:
                        return update
                raise AssertionError("no video stream info")

            update = await asyncio.wait_for(first_stream(), 60)
            assert update.component_id == CAMERA  # type: ignore[attr-defined]
            # The list once the stream is known: the camera component alone (an autopilot that
            # answers for the camera is listed too, as a second camera of component 1).
            cameras = await asyncio.wait_for(listed(), 60)
            assert [c.component_id for c in cameras] == [CAMERA]  # type: ignore[attr-defined]
            cam = cameras[0]
            assert cam.vendor_name == "air-sitl"  # type: ignore[attr-defined]
            assert cam.horizontal_resolution_px == 320  # type: ignore[attr-defined]
            info = update.video_stream_info  # type: ignore[attr-defined]
            assert info.settings.uri == f"udp://0.0.0.0:{video}"
            assert (
                info.settings.horizontal_resolution_pix,
                info.settings.vertical_resolution_pix,
            ) == (320, 240)
            assert info.status == info.VideoStreamStatus.IN_PROGRESS

    with serve("--mavlink", f"udpout:127.0.0.1:{port}", "--video", f"udp://127.0.0.1:{video}",
               *SMALL):  # fmt: skip
        asyncio.run(check())


def _mission(home: GeoPoint, north_m: float) -> list[MissionItem]:
    """Take off, then a waypoint ``north_m`` north of home, 80 m up."""
    lat, lon, _ = ned2geodetic(north_m, 0.0, 0.0, home.lat_deg, home.lon_deg, 0.0)
    return [
        MissionItem(command=MavCmd.NAV_TAKEOFF, param1=15.0, lat_deg=home.lat_deg,
                    lon_deg=home.lon_deg, alt_m=80.0),
        MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=lat, lon_deg=lon, alt_m=80.0),
    ]  # fmt: skip


def test_two_instances_one_ground_station_two_missions_two_streams(tmp_path: Path) -> None:
    gcs_port, offboard, video = udp_port(), port_pair(), port_pair()
    common = ("--gcs-port", str(gcs_port), "--offboard-base-port", str(offboard),
              "--video-base-port", str(video), "--speed", "4", *SMALL)  # fmt: skip
    api = QgcLike(f"udpin:127.0.0.1:{offboard + 1}")  # MAVSDK's port of instance 1
    gcs = QgcLike(f"udpin:127.0.0.1:{gcs_port}")  # QGC's, shared
    try:
        with (
            serve("--instance", "0", *common) as first,
            serve("--instance", "1", *common) as second,
        ):
            gcs.wait_heard({(1, 1), (2, 1), (1, CAMERA), (2, CAMERA)})
            api.wait_heard({(2, 1)})
            assert (1, 1) not in api.heard  # instance 0 has its own API port
            homes = {}
            for system in (1, 2):
                msg = gcs.recv(["HOME_POSITION"], system)
                homes[system] = GeoPoint(lat_deg=msg.latitude / 1e7, lon_deg=msg.longitude / 1e7,
                                         alt_amsl_m=msg.altitude / 1000)  # fmt: skip
            east_m = (
                (homes[2].lon_deg - homes[1].lon_deg)
                * 111_320
                * np.cos(np.radians(homes[1].lat_deg))
            )
            assert east_m == pytest.approx(20.0, abs=0.5)  # instance 1 stands 20 m east
            for system, north in ((1, 600.0), (2, -600.0)):
                assert gcs.upload(system, _mission(homes[system], north)) == M.MAV_MISSION_ACCEPTED
            for system in (1, 2):
                mode = gcs.command(system, 1, M.MAV_CMD_DO_SET_MODE, *PX4_MISSION)
                assert mode == M.MAV_RESULT_ACCEPTED
                arm = gcs.command(system, 1, M.MAV_CMD_COMPONENT_ARM_DISARM, 1)
                assert arm == M.MAV_RESULT_ACCEPTED
            up: dict[int, float] = {}
            deadline = time.monotonic() + 120
            while not all(up.get(s, 0.0) > 40.0 for s in (1, 2)):
                assert time.monotonic() < deadline, f"climbed only {up}"
                msg = gcs.recv(["GLOBAL_POSITION_INT"], timeout_s=5.0)
                if msg is not None:
                    up[msg.get_srcSystem()] = msg.relative_alt / 1000
            with gst_viewer(video, 320, 240, tmp_path, "uav0") as v0, \
                    gst_viewer(video + 1, 320, 240, tmp_path, "uav1") as v1:  # fmt: skip
                wait_frames(v0, 10)
                wait_frames(v1, 10)
                a, b = v0.frame(-1).astype(float), v1.frame(-1).astype(float)
            assert a.std() > 5 and b.std() > 5
            assert float(np.abs(a - b).mean()) > 10.0  # two places, two pictures
            for served in (first, second):
                code, out = served.stop()
                assert code == 0 and "video:" in out
    finally:
        gcs.close()
        api.close()


def test_mavsdk_connects_to_each_instance_on_its_own_port() -> None:
    gcs_port, offboard = udp_port(), port_pair()
    common = ("--gcs-port", str(gcs_port), "--offboard-base-port", str(offboard), "--no-video")

    async def home_on(port: int) -> tuple[float, float]:
        async with ground_station(port, timeout_s=60) as system:
            async for home in TelemetryAsync(system).subscribe_home():
                return home.latitude_deg, home.longitude_deg
        raise AssertionError("no home position")

    with serve("--instance", "0", *common), serve("--instance", "1", *common):
        (lat0, lon0), (lat1, lon1) = (asyncio.run(home_on(offboard + n)) for n in (0, 1))
    east_m = (lon1 - lon0) * 111_320 * np.cos(np.radians(lat0))
    assert lat1 == pytest.approx(lat0, abs=1e-6)
    assert east_m == pytest.approx(20.0, abs=0.5)  # each port, its own vehicle
