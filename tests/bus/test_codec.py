"""The message encoding: exact round trips, and one-line reasons for bad estimates."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from air_sitl.bus import codec
from air_sitl.bus.keys import CONTRACT_VERSION, KeySpace
from air_sitl.errors import AirSitlError, BusError, OptionError
from air_sitl.state import GeoPoint

from .helpers import make_sample

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(finite, finite, finite, st.integers(0, 2**62))
def test_truth_round_trip_is_bit_exact(a: float, b: float, c: float, t: int) -> None:
    # The remote camera renders from the decoded state: any float change would change pixels.
    sample = make_sample(t)
    state = sample.state.__class__(
        **{**codec.encode_state(sample.state), "pos_ned_m": (a, b, c), "lat_deg": a}
    )
    m = codec.loads(codec.encode_truth(state, 7), "truth")
    assert m["v"] == CONTRACT_VERSION and m["frame"] == 7
    assert codec.decode_state(m) == state


def test_imu_round_trip() -> None:
    imu = make_sample(5_000_000).imu
    assert codec.decode_imu(codec.encode_imu(imu)) == imu


def test_gps_and_status_messages_name_their_units() -> None:
    sample = make_sample(200_000_000, gps=True)
    assert sample.gps is not None
    gps = json.loads(codec.encode_gps(sample.gps))
    assert gps["sim_time_ns"] == 200_000_000 and gps["fix_type"] == 3
    assert set(gps) >= {"lat_deg", "lon_deg", "alt_amsl_m", "vel_ned_m_s", "eph_m"}
    home = GeoPoint(lat_deg=1.0, lon_deg=2.0, alt_amsl_m=3.0)
    status = json.loads(codec.encode_status(0, sample.autopilot, home))
    assert status["mode"] == "mission" and status["capturing"] is True
    assert status["home"] == {"lat_deg": 1.0, "lon_deg": 2.0, "alt_amsl_m": 3.0}


def test_frame_meta_round_trip_and_missing_attachment() -> None:
    meta = codec.FrameMeta(frame=3, sim_time_ns=60_000_000, width_px=640, height_px=480)
    assert codec.decode_frame_meta(codec.encode_frame_meta(meta)) == meta
    with_xy = codec.FrameMeta(
        frame=3, sim_time_ns=1, width_px=640, height_px=480, map_xy_px=(10, -1)
    )
    assert codec.decode_frame_meta(codec.encode_frame_meta(with_xy)) == with_xy
    with pytest.raises(BusError, match="no attachment"):
        codec.decode_frame_meta(None)


def test_camera_info_has_the_spec_focal_length() -> None:
    info = codec.CameraInfo(
        width_px=640, height_px=480, hfov_deg=57.0, rate_hz=50.0, q_cam_to_body_wxyz=(1, 0, 0, 0)
    )
    m = json.loads(codec.encode_camera_info(info))
    assert m["fx_px"] == pytest.approx(589.3, abs=0.1) and m["fy_px"] == m["fx_px"]
    assert (m["cx_px"], m["cy_px"]) == (319.5, 239.5)
    assert codec.decode_camera_info(codec.encode_camera_info(info)) == info


@pytest.mark.parametrize(
    ("message", "expected"),
    [
        ({"frame": 4, "enu_m": [1, 2, 3]}, codec.Estimate(frame=4, sim_time_ns=None,
                                                          enu_m=(1.0, 2.0, 3.0), geo=None)),
        ({"sim_time_ns": 20, "lat_deg": 54.0, "lon_deg": 25.0, "alt_amsl_m": 300},
         codec.Estimate(frame=None, sim_time_ns=20, enu_m=None,
                        geo=GeoPoint(lat_deg=54.0, lon_deg=25.0, alt_amsl_m=300.0))),
        ({"frame": 1}, codec.Estimate(frame=1, sim_time_ns=None, enu_m=None, geo=None)),
    ],
)  # fmt: skip
def test_estimates_accepted(message: dict[str, object], expected: codec.Estimate) -> None:
    assert codec.decode_estimate(json.dumps(message).encode(), "e") == expected


def test_null_coordinates_mean_no_estimate_but_still_an_answer() -> None:
    est = codec.decode_estimate(b'{"frame": 2, "enu_m": [null, null, null]}', "e")
    assert est.frame == 2 and est.enu_m is not None and all(math.isnan(c) for c in est.enu_m)


@pytest.mark.parametrize(
    ("payload", "reason"),
    [
        (b"not json", "not a JSON object"),
        (b"[1, 2]", "expected a JSON object"),
        (b'{"enu_m": [1, 2, 3]}', "needs 'frame' or 'sim_time_ns'"),
        (b'{"frame": 1, "enu_m": [1, 2]}', "'enu_m' needs 3 numbers"),
        (b'{"frame": 1, "lat_deg": 91, "lon_deg": 0, "alt_amsl_m": 0}', "out of range"),
        (b'{"frame": 1, "enu_m": [1, 2, 3], "cov_enu_m2": [1, 2]}', "9 numbers"),
    ],
)
def test_bad_estimates_have_a_one_line_reason(payload: bytes, reason: str) -> None:
    with pytest.raises(BusError, match=reason) as info:
        codec.decode_estimate(payload, "air/uav0/estimate/x")
    assert "\n" not in str(info.value) and "air/uav0/estimate/x" in str(info.value)
    assert isinstance(info.value, AirSitlError)


def test_key_space_is_versioned_under_the_vehicle() -> None:
    keys = KeySpace("uav7")
    assert keys.image == "air/uav7/camera/image"
    assert keys.info == "air/uav7/camera/info"
    assert (keys.imu, keys.gps, keys.truth) == ("air/uav7/imu", "air/uav7/gps", "air/uav7/truth")
    assert (keys.mission_status, keys.clock) == ("air/uav7/mission/status", "air/uav7/clock")
    assert keys.estimate("vo") == "air/uav7/estimate/vo"
    assert keys.estimates == "air/uav7/estimate/*"
    for bad in ("", "a/b", "a*", "x y", "$x"):
        with pytest.raises(OptionError):
            KeySpace(bad)
