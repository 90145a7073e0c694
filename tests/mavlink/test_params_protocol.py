"""The parameter protocol as PX4 answers it: what QGroundControl and MAVProxy read at connect,
typed as PX4 types it; unknown names; sets stored as sent (no range check)."""

from __future__ import annotations

import struct
from collections.abc import Iterator

import pytest
from gcs import Gcs
from inproc import Vehicle, running_vehicle
from pymavlink import mavutil

from air_sitl.state import GeoPoint

M = mavutil.mavlink
HOME = GeoPoint(lat_deg=47.397742, lon_deg=8.545594, alt_amsl_m=488.0)
INT32 = {"SYS_AUTOSTART", "MAV_SYS_ID", "MAV_TYPE", "COM_DL_LOSS_T", "NAV_DLL_ACT",
         "EKF2_EV_CTRL", "EKF2_GPS_CTRL", "EKF2_EV_NOISE_MD", "COM_LOW_BAT_ACT", "BAT1_N_CELLS",
         "CAL_ACC0_ID", "GF_ACTION", "RTL_TYPE"}  # fmt: skip
REAL32 = {"FW_R_LIM", "FW_AIRSPD_TRIM", "NAV_LOITER_RAD", "RTL_RETURN_ALT", "EKF2_EVP_NOISE",
          "RTL_DESCEND_ALT", "COM_RC_LOSS_T", "BAT1_CAPACITY", "BAT_LOW_THR"}  # fmt: skip
pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def vehicle_gcs() -> Iterator[tuple[Vehicle, Gcs]]:
    with running_vehicle(["udpin:127.0.0.1:0"], HOME, speed=1.0) as vehicle:
        gcs = Gcs(f"udpout:127.0.0.1:{vehicle.endpoint.links[0].local_address[1]}")
        gcs.connect()
        yield vehicle, gcs
        gcs.close()


def value_of(msg: object) -> float:
    """PARAM_VALUE's value, INT32 decoded bytewise (PX4 encodes integers so)."""
    if msg.param_type == M.MAV_PARAM_TYPE_INT32:  # type: ignore[attr-defined]
        return float(struct.unpack("<i", struct.pack("<f", msg.param_value))[0])  # type: ignore[attr-defined]
    return float(msg.param_value)  # type: ignore[attr-defined]


def read(gcs: Gcs, name: str) -> object:
    gcs.conn.mav.param_request_read_send(1, 1, name.encode(), -1)
    while True:
        msg = gcs.recv(["PARAM_VALUE"])
        assert msg is not None, f"no PARAM_VALUE for {name}"
        if msg.param_id == name:
            return msg


def test_connect_time_parameters_are_served_with_px4_types(
    vehicle_gcs: tuple[Vehicle, Gcs],
) -> None:
    _vehicle, gcs = vehicle_gcs
    autostart = read(gcs, "SYS_AUTOSTART")
    assert autostart.param_type == M.MAV_PARAM_TYPE_INT32  # type: ignore[attr-defined]
    assert value_of(autostart) == 2100
    assert value_of(read(gcs, "MAV_TYPE")) == M.MAV_TYPE_FIXED_WING
    gcs.conn.mav.param_request_list_send(1, 1)
    types: dict[str, int] = {}
    total = None
    while total is None or len(types) < total:
        msg = gcs.recv(["PARAM_VALUE"])
        assert msg is not None
        total = msg.param_count
        types[msg.param_id] = msg.param_type
    assert total > 60
    for name in INT32:
        assert types[name] == M.MAV_PARAM_TYPE_INT32, name
    for name in REAL32:
        assert types[name] == M.MAV_PARAM_TYPE_REAL32, name
    assert any(n.startswith("COM_") for n in types) and any(n.startswith("NAV_") for n in types)


def test_an_unknown_name_gets_px4s_statustext_and_no_value(
    vehicle_gcs: tuple[Vehicle, Gcs],
) -> None:
    _vehicle, gcs = vehicle_gcs
    gcs.conn.mav.param_request_read_send(1, 1, b"NO_SUCH_PARAM", -1)
    gcs.wait_text("[pm] unknown param: NO_SUCH_PARAM")
    gcs.conn.mav.param_request_read_send(1, 1, b"", 9999)
    gcs.wait_text("[pm] unknown param ID: 9999")
    gcs.conn.mav.param_set_send(1, 1, b"NO_SUCH_PARAM", 1.0, M.MAV_PARAM_TYPE_REAL32)
    texts = len(gcs.texts)
    gcs.wait_text("[pm] unknown param: NO_SUCH_PARAM")
    # Nothing answered with a PARAM_VALUE for it, before or after.
    later = gcs.collect(["PARAM_VALUE"], 1.0)
    assert all(m.param_id != "NO_SUCH_PARAM" for m in later)
    assert len(gcs.texts) >= texts


def test_a_set_outside_the_range_is_stored_and_the_controller_clamps(
    vehicle_gcs: tuple[Vehicle, Gcs],
) -> None:
    vehicle, gcs = vehicle_gcs
    assert gcs.set_param("FW_R_LIM", 80.0) == pytest.approx(80.0)  # PX4: stored as sent
    assert value_of(read(gcs, "FW_R_LIM")) == pytest.approx(80.0)
    params = vehicle.flight.autopilot.params
    assert params.get("FW_R_LIM") == 80.0
    assert params.in_range("FW_R_LIM") == 65.0  # the bank limit flown: the range's top
    assert gcs.set_param("FW_R_LIM", 35.0) == pytest.approx(35.0)
