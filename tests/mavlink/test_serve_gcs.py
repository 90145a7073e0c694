"""``air-sitl serve`` with pymavlink as a plain ground station: what QGroundControl does by hand.

Each test starts the real command (a process) on loopback and talks MAVLink to it.
"""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path

import pytest
from gcs import PX4_MISSION, Gcs, serve
from pymavlink import mavutil

from air_sitl.camera.info import camera_yaml_for
from air_sitl.camera.model import CameraModel
from air_sitl.frames import ned2geodetic
from air_sitl.mavlink.codec import (
    Encoder,
    ParseCounters,
    Parser,
    from_mission_message,
    to_mission_message,
)
from air_sitl.mavlink.messages import MissionItemMessage
from air_sitl.mavlink.mission_protocol import same_items
from air_sitl.mavlink.telemetry import custom_mode
from air_sitl.mission.items import MavCmd, MissionItem
from air_sitl.mission.plan_file import load_mission, write_plan
from air_sitl.state import FlightMode

REPO = Path(__file__).resolve().parents[2]
UC200 = REPO / "missions" / "UC-200.plan"
M = mavutil.mavlink
pytestmark = pytest.mark.integration


def fence_around(lat: float, lon: float, radius_m: float) -> list[MissionItem]:
    return [
        MissionItem(
            command=MavCmd.NAV_FENCE_CIRCLE_INCLUSION,
            param1=radius_m,
            lat_deg=lat,
            lon_deg=lon,
        )
    ]


def same_wire_items(got: Sequence[MissionItem], sent: Sequence[MissionItem]) -> bool:
    """Equal as MISSION_ITEM_INT carries them (degE7 positions, float32 params)."""
    wire = []
    encoder, parser = Encoder(1, 1), Parser(ParseCounters())
    for seq, item in enumerate(sent):
        frame = encoder.encode(from_mission_message(MissionItemMessage(seq=seq, item=item), 1, 1))
        (decoded,) = parser.feed(frame, datagram=True)
        msg = to_mission_message(decoded)
        assert isinstance(msg, MissionItemMessage)
        wire.append(msg.item)
    return same_items(got, wire)


def test_ci_smoke_flight_uc200_records_a_valid_archive(tmp_path: Path) -> None:
    """Upload UC-200 by hand, fence, rally, parameters, QGC's mode + arm, fly it, check it.

    UC-200's items on the short course (:func:`write_short_circle_plan`): each item the same
    kind of work in under a quarter of the flight; nothing checked depends on the course's size."""
    mission = load_mission(write_short_circle_plan(tmp_path / "short-circle.plan"))
    home = mission.planned_home
    assert home is not None
    out = tmp_path / "rec"
    with serve(
        "--mavlink", "udpin:127.0.0.1:0",
        "--home", f"{home.lat_deg},{home.lon_deg},{home.alt_amsl_m}",
        "--speed", "100",
        "--out", str(out),
        "--camera-width", "160", "--camera-height", "120", "--noise-sigma", "0",
    ) as served:  # fmt: skip
        gcs = Gcs(f"udpout:127.0.0.1:{served.ports[0]}")
        hb = gcs.connect()
        assert (hb.type, hb.autopilot) == (M.MAV_TYPE_FIXED_WING, M.MAV_AUTOPILOT_PX4)
        assert not hb.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED

        # Parameters: list, set, read back.
        params = gcs.params()
        assert {"FW_AIRSPD_TRIM", "NAV_LOITER_RAD", "RTL_RETURN_ALT", "FW_R_LIM"} <= set(params)
        assert gcs.set_param("NAV_LOITER_RAD", 90.0) == pytest.approx(90.0)
        assert gcs.set_param("FW_R_LIM", 80.0) == pytest.approx(80.0)  # stored, as PX4
        assert gcs.set_param("FW_R_LIM", 35.0) == pytest.approx(35.0)
        assert gcs.params()["NAV_LOITER_RAD"] == pytest.approx(90.0)

        # Mission, fence and rally: upload, download, compare.
        fence = fence_around(home.lat_deg, home.lon_deg, 5000.0)
        rally = [
            MissionItem(
                command=MavCmd.NAV_RALLY_POINT,
                lat_deg=home.lat_deg + 0.001,
                lon_deg=home.lon_deg,
                alt_m=50.0,
            )
        ]
        assert gcs.upload(mission.items) == M.MAV_MISSION_ACCEPTED
        assert gcs.upload(fence, mission_type=1) == M.MAV_MISSION_ACCEPTED
        assert gcs.upload(rally, mission_type=2) == M.MAV_MISSION_ACCEPTED
        assert same_wire_items(gcs.download(), mission.items)
        assert same_wire_items(gcs.download(mission_type=1), fence)
        assert same_wire_items(gcs.download(mission_type=2), rally)

        # What QGroundControl does to start: DO_SET_MODE (1, 4, 4), then arm.
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        reached: list[int] = []
        armed_in_mission = False
        finished = False
        nav = [i for i, item in enumerate(mission.items) if item.is_nav]
        # PX4's order: MISSION_CURRENT says COMPLETE first, then the last item is reported
        # reached in the same burst (MAVSDK's progress and is_mission_finished agree).
        while not (finished and set(nav) <= set(reached)):
            msg = gcs.recv(["MISSION_ITEM_REACHED", "MISSION_CURRENT", "HEARTBEAT"])
            assert msg is not None, f"the vehicle went silent; reached {reached}"
            if msg.get_type() == "HEARTBEAT" and msg.get_srcSystem() == 1:
                armed_in_mission |= bool(
                    msg.base_mode & M.MAV_MODE_FLAG_SAFETY_ARMED
                    and msg.custom_mode == custom_mode(FlightMode.MISSION)
                )
            elif msg.get_type() == "MISSION_ITEM_REACHED":
                reached.append(msg.seq)
            elif msg.get_type() == "MISSION_CURRENT":
                finished = msg.mission_state == 5  # MISSION_STATE_COMPLETE
        assert armed_in_mission
        for text in ("Armed", "Takeoff", "Capture started", "Capture stopped", "Mission finished"):
            gcs.wait_text(text)
        gcs.close()
        code, stdout = served.stop()
    assert code == 0, stdout
    assert "recorded" in stdout
    check = subprocess.run(
        [sys.executable, "-m", "air_sitl", "check", str(out / "1")],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert check.returncode == 0, check.stdout + check.stderr
    assert "VALID" in check.stdout
    # The archive describes its camera as `fly` archives do: in camera.yaml and the manifest.
    served_camera = CameraModel(width_px=160, height_px=120, noise_sigma=0.0)
    assert (out / "1" / "camera.yaml").read_text() == camera_yaml_for(served_camera)
    manifest = json.loads((out / "1" / "manifest.json").read_text())
    assert manifest["camera"]["width_px"] == 160 and manifest["camera"]["noise_sigma"] == 0.0
    assert manifest["home"]["lat_deg"] == pytest.approx(home.lat_deg)
    assert manifest["recorded_by"] == "air-sitl serve"


def test_geofence_breach_returns_to_launch() -> None:
    mission = load_mission(UC200)
    home = mission.planned_home
    assert home is not None
    with serve("--mavlink", "udpin:127.0.0.1:0", "--plan", str(UC200), "--speed", "100") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        fence = fence_around(home.lat_deg, home.lon_deg, 400.0)  # the plan goes 1-3 km away
        assert gcs.upload(fence, mission_type=1) == M.MAV_MISSION_ACCEPTED
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_ACCEPTED
        rtl = False
        while not rtl:
            hb = gcs.recv(["HEARTBEAT"])
            assert hb is not None, gcs.texts
            rtl = hb.get_srcComponent() == 1 and hb.custom_mode == custom_mode(FlightMode.RTL)
        gcs.wait_text("Geofence")
        pos = gcs.recv(["GLOBAL_POSITION_INT"])
        assert pos is not None and pos.relative_alt > 20_000  # flying, not on the ground
        gcs.close()


def test_commands_prearm_takeoff_and_params_in_flight() -> None:
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", "50") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        # Bad items over the wire get their MAV_MISSION_RESULT; the (empty) mission stays.
        good = MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=47.4, lon_deg=8.5, alt_m=50)
        bad_lat = dataclasses.replace(good, lat_deg=91.0)
        unknown = dataclasses.replace(good, command=4242)
        jump = MissionItem(command=MavCmd.DO_JUMP, frame=2, param1=9, param2=1)
        assert gcs.upload([good, bad_lat]) == M.MAV_MISSION_INVALID_PARAM5_X
        assert gcs.upload([unknown]) == M.MAV_MISSION_UNSUPPORTED
        assert gcs.upload([good, jump]) == M.MAV_MISSION_INVALID_SEQUENCE
        gcs.conn.mav.mission_count_send(1, 1, 65535, 0)
        assert gcs.recv(["MISSION_ACK"]).type == M.MAV_MISSION_NO_SPACE
        assert gcs.download() == []
        # No mission: MISSION mode refused, with the reason as STATUSTEXT.
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_DENIED
        gcs.wait_text("no mission")
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, 1, 6, 0) == M.MAV_RESULT_UNSUPPORTED  # OFFBOARD
        assert gcs.command(M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1) == M.MAV_RESULT_UNSUPPORTED
        assert gcs.command(M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_DENIED  # on ground
        # AUTOPILOT_VERSION with MISSION_INT, HOME_POSITION on request; CAMERA_INFORMATION is the
        # camera component's (test_camera_component), not the autopilot's.
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 148) == M.MAV_RESULT_ACCEPTED
        version = gcs.recv(["AUTOPILOT_VERSION"])
        assert version.capabilities & M.MAV_PROTOCOL_CAPABILITY_MISSION_INT
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 242) == M.MAV_RESULT_ACCEPTED
        assert gcs.recv(["HOME_POSITION"]).latitude == round(47.397742 * 1e7)
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 259) == M.MAV_RESULT_UNSUPPORTED
        assert gcs.command(M.MAV_CMD_REQUEST_MESSAGE, 9999) == M.MAV_RESULT_UNSUPPORTED
        # TIMESYNC
        gcs.conn.mav.timesync_send(0, 123456789)
        sync = gcs.recv(["TIMESYNC"])
        assert sync.ts1 == 123456789 and sync.tc1 > 0

        # Arm and take off (PX4 style: NaN altitude = MIS_TAKEOFF_ALT).
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        nan = math.nan
        assert gcs.command(M.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, nan) == (
            M.MAV_RESULT_ACCEPTED
        )
        in_air = False
        while not in_air:
            ext = gcs.recv(["EXTENDED_SYS_STATE"])
            assert ext is not None
            in_air = ext.landed_state == M.MAV_LANDED_STATE_IN_AIR
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 0) == M.MAV_RESULT_DENIED  # in air
        # A parameter changed in flight takes effect: trim airspeed 15 -> 20 m/s.
        assert gcs.set_param("FW_AIRSPD_TRIM", 20.0) == pytest.approx(20.0)
        # Within 60 simulated seconds (by the clock of the telemetry).
        huds = []
        start = gcs.sim_ms
        while not huds or huds[-1].airspeed <= 18.5:
            hud = gcs.recv(["VFR_HUD"])
            assert hud is not None and gcs.sim_ms - start < 60_000, "FW_AIRSPD_TRIM had no effect"
            huds.append(hud)
        assert gcs.command(M.MAV_CMD_DO_CHANGE_SPEED, 0, 16, -1) == M.MAV_RESULT_ACCEPTED
        reposition = (-1, 1, 0, nan, 47.40, 8.55, nan)
        assert gcs.command(M.MAV_CMD_DO_REPOSITION, *reposition) == M.MAV_RESULT_ACCEPTED
        hb = gcs.recv(["HEARTBEAT"])
        while hb.get_srcComponent() != 1:
            hb = gcs.recv(["HEARTBEAT"])
        assert hb.custom_mode == custom_mode(FlightMode.LOITER)
        assert gcs.command(M.MAV_CMD_IMAGE_START_CAPTURE, 0, 0.02) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_IMAGE_STOP_CAPTURE) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_NAV_RETURN_TO_LAUNCH) == M.MAV_RESULT_ACCEPTED
        gcs.close()


def _fly_to_end(gcs: Gcs, last: int) -> list[int]:
    """The items reported reached up to the ``last`` one. MISSION_CURRENT says COMPLETE before
    that last MISSION_ITEM_REACHED (MAVSDK's progress reaches its total on it, and from then on
    its ``is_mission_finished`` must say yes: issue 33)."""
    reached: list[int] = []
    state = -1
    while True:
        msg = gcs.recv(["MISSION_CURRENT", "MISSION_ITEM_REACHED"])
        assert msg is not None, f"the vehicle went silent; reached {reached}"
        if msg.get_type() == "MISSION_CURRENT":
            state = msg.mission_state
            continue
        reached.append(msg.seq)
        if msg.seq == last:
            assert state == M.MISSION_STATE_COMPLETE, (reached, state)
            return reached


def write_short_circle_plan(path: Path) -> Path:
    """UC-200's items (take-off, speed, two waypoints, capture start, one loiter turn, capture
    stop, RTL) on a 1.7 km course instead of 7.5 km (a loiter radius of 80 m instead of 162): the
    same sequence in under a quarter of the flight."""
    uc200 = load_mission(UC200)
    home = uc200.planned_home
    assert home is not None

    def north_east(item: MissionItem, north_m: float, east_m: float, alt_m: float) -> MissionItem:
        lat, lon, _ = ned2geodetic(north_m, east_m, 0.0, home.lat_deg, home.lon_deg, 0.0)
        return dataclasses.replace(item, lat_deg=lat, lon_deg=lon, alt_m=alt_m)

    takeoff, speed, wp1, wp2, start, circle, stop, rtl = uc200.items
    assert circle.command == MavCmd.NAV_LOITER_TURNS and rtl.command == MavCmd.NAV_RETURN_TO_LAUNCH
    items = (
        north_east(takeoff, 300.0, 0.0, 80.0), speed,
        north_east(wp1, 450.0, 0.0, 80.0), north_east(wp2, 600.0, 0.0, 80.0), start,
        dataclasses.replace(north_east(circle, 600.0, 80.0, 80.0), param3=80.0), stop, rtl,
    )  # fmt: skip
    write_plan(dataclasses.replace(uc200, items=items), path)
    return path


def test_the_preloaded_mission_flies_twice_without_restart(tmp_path: Path) -> None:
    plan = write_short_circle_plan(tmp_path / "short-circle.plan")
    with serve("--mavlink", "udpin:127.0.0.1:0", "--plan", str(plan), "--speed", "150") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        assert gcs.command(M.MAV_CMD_COMPONENT_ARM_DISARM, 1) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_ACCEPTED  # MAVSDK way
        assert _fly_to_end(gcs, 7) == [0, 2, 3, 5, 7]
        # -1 keeps the current item (common.xml), with or without the reset of param2.
        assert gcs.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, -1) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, -1, 1) == M.MAV_RESULT_ACCEPTED
        # Again, from item 2 this time (still in the air, loitering at home).
        assert gcs.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, 2) == M.MAV_RESULT_ACCEPTED
        assert gcs.command(M.MAV_CMD_DO_SET_MISSION_CURRENT, 99) == M.MAV_RESULT_DENIED
        assert gcs.command(M.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == M.MAV_RESULT_ACCEPTED
        assert _fly_to_end(gcs, 7) == [2, 3, 5, 7]
        gcs.close()


def test_a_long_statustext_arrives_in_chunks() -> None:
    """More than 50 characters: MAVLink 2 chunks sharing a non-zero id, chunk_seq 0, 1, ..."""
    far = MissionItem(command=MavCmd.NAV_WAYPOINT, lat_deg=10.0, lon_deg=10.0, alt_m=50)
    with serve("--mavlink", "udpin:127.0.0.1:0", "--speed", "5") as s:
        gcs = Gcs(f"udpout:127.0.0.1:{s.ports[0]}")
        gcs.connect()
        assert gcs.upload([far]) == M.MAV_MISSION_ACCEPTED
        assert gcs.command(M.MAV_CMD_MISSION_START, 0, 0) == M.MAV_RESULT_DENIED
        gcs.wait_text("Mission start denied")
        first = next(m for m in gcs.statustexts if m.text.startswith("Mission start denied"))
        assert first.id != 0 and first.chunk_seq == 0
        chunks = [m for m in gcs.statustexts if m.id == first.id]
        while len(chunks[-1].text) == 50:
            msg = gcs.recv(["STATUSTEXT"])
            assert msg is not None
            if msg.id == first.id:
                chunks.append(msg)
        assert [c.chunk_seq for c in chunks] == list(range(len(chunks)))
        assert len(chunks) >= 2
        text = "".join(c.text for c in chunks)
        assert text.startswith("Mission start denied: first waypoint is")
        assert text.endswith("or plan near the vehicle")
        gcs.close()
