"""The localizer framework without flights: types, registry, input models, output format."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from air_sitl.bus import codec
from air_sitl.bus.estimate_contract import EstimateRejectedError
from air_sitl.bus.estimates import ESTIMATE_COLUMNS
from air_sitl.camera.model import CameraModel
from air_sitl.dataset.estimates import parse_estimates
from air_sitl.errors import DatasetError
from air_sitl.eval.sources import parse_csv
from air_sitl.frames import euler2quat, ned2geodetic
from air_sitl.localize import METHODS, Estimate, Localizer, LocalizerContext, Observation
from air_sitl.localize.archive import _fix_of, check_writable, denial_windows
from air_sitl.localize.base import GnssFix, ImuReading
from air_sitl.localize.deadreckon import WIND_MIN_FIXES, DeadReckoning
from air_sitl.localize.inputs import AirspeedModel, BaroModel, fix_position_ned
from air_sitl.localize.online import camera_from_info
from air_sitl.localize.output import estimate_row
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
FRAME_NS = 20_000_000


@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_registered_method_keeps_the_protocol(method: str) -> None:
    loc = METHODS[method]()
    assert isinstance(loc, Localizer)
    assert isinstance(loc.name, str) and isinstance(loc.needs_image, bool)


def test_rows_parse_back_and_no_position_is_no_estimate() -> None:
    q = euler2quat(0.1, 0.0, 1.0)
    rows = [
        Estimate(frame=0, sim_time_ns=5, enu_m=(1.5, -2.25, 200.0), q_body_to_ned_wxyz=q),
        Estimate(frame=1, sim_time_ns=6, enu_m=None),
        Estimate(frame=2, sim_time_ns=7, enu_m=(math.nan, 0.0, 0.0)),
    ]
    text = ",".join(ESTIMATE_COLUMNS) + "\n" + "".join(estimate_row(r, HOME) for r in rows)
    points = parse_estimates(text, "x.csv", HOME)
    assert len(points) == 1
    p = points[0]
    assert (p.frame, p.sim_time_ns, p.enu_m) == (0, 5, (1.5, -2.25, 200.0))
    assert p.q_body_to_ned_wxyz == pytest.approx(q, abs=1e-8)
    fields = estimate_row(rows[0], HOME).rstrip("\n").split(",")
    lat, lon, _alt = ned2geodetic(-2.25, 1.5, -200.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    assert float(fields[5]) == pytest.approx(lat, abs=1e-9)
    assert float(fields[6]) == pytest.approx(lon, abs=1e-9)
    assert fields[-3:] == ["", "", ""]  # latency: none offline; fix: the method does not say


def test_the_fix_column_round_trips_through_the_csv_and_the_bus() -> None:
    """``fix`` is the last column: 1 / 0 / empty, read back by eval as 1 / 0 / NaN; on the
    bus an optional boolean, recorded when present."""
    assert ESTIMATE_COLUMNS[-1] == "fix"
    said = (True, False, None, True)
    rows = [
        Estimate(frame=k, sim_time_ns=5 + k, enu_m=(1.0, 2.0, 3.0) if k != 1 else None, fix=f)
        for k, f in enumerate(said)
    ]
    lines = [estimate_row(r, HOME) for r in rows]
    assert [ln.rstrip("\n").split(",")[-1] for ln in lines] == ["1", "0", "", "1"]
    text = ",".join(ESTIMATE_COLUMNS) + "\n" + "".join(lines)
    parsed = parse_csv(text, "x.csv", "x", HOME)
    assert parsed.fix is not None
    assert parsed.fix[[0, 1, 3]].tolist() == [1.0, 0.0, 1.0] and math.isnan(parsed.fix[2])
    assert len(parse_estimates(text, "x.csv", HOME)) == 3  # the dataset reader skips it
    for fix in said:
        payload = codec.encode_estimate(frame=3, enu_m=(1.0, 2.0, 3.0), fix=fix)
        assert (b'"fix"' in payload) == (fix is not None)
        assert codec.decode_estimate(payload, "k").fix is fix
    with pytest.raises(EstimateRejectedError, match="'fix' must be true, false or null"):
        codec.decode_estimate(b'{"frame": 3, "fix": 1}', "k")


def test_input_models_are_seeded_and_sized() -> None:
    n = 30_000  # 10 minutes at 50 Hz
    t = np.arange(n, dtype=np.int64) * FRAME_NS
    truth = np.full(n, 200.0)
    a = BaroModel().sample(truth, t, 3)
    assert np.array_equal(a, BaroModel().sample(truth, t, 3))
    assert not np.array_equal(a, BaroModel().sample(truth, t, 4))
    white = np.diff(a)  # the walk's steps are tiny beside the white noise
    assert np.std(white) / math.sqrt(2) == pytest.approx(0.5, rel=0.05)
    assert abs(np.mean(a[-500:]) - 200.0) < 6.0  # 0.05 m/sqrt(s) over 600 s: sigma 1.2 m
    s = AirspeedModel().sample(np.full(n, 15.0), 3)
    assert np.std(s) == pytest.approx(0.3, rel=0.05) and abs(np.mean(s) - 15.0) < 0.01


def _fix(t_ns: int, north_m: float, east_m: float, vel: tuple[float, float]) -> GnssFix:
    lat, lon, alt = ned2geodetic(
        north_m, east_m, -200.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m
    )
    return GnssFix(
        sim_time_ns=t_ns, lat_deg=lat, lon_deg=lon, alt_amsl_m=alt, vel_ned_m_s=(*vel, 0.0)
    )


def test_a_fix_is_moved_on_to_the_frame_time() -> None:
    n, e, d = fix_position_ned(_fix(0, 10.0, 20.0, (15.0, -3.0)), HOME, 200_000_000)
    assert (n, e, d) == pytest.approx((13.0, 19.4, -200.0), abs=1e-6)


def _context() -> LocalizerContext:
    return LocalizerContext(home=HOME, camera=CameraModel())


def _observations(
    frames: int, heading_rad: float, airspeed: float, fixes: bool
) -> list[Observation]:
    q = euler2quat(0.0, 0.0, heading_rad)
    out = []
    for k in range(frames):
        t = k * FRAME_NS
        imu = tuple(
            ImuReading(
                sim_time_ns=t - j * 5_000_000,
                gyro_frd_rad_s=(0.0, 0.0, 0.0),
                accel_frd_m_s2=(0.0, 0.0, -9.8),
                q_ahrs_body_to_ned_wxyz=q,
            )
            for j in (3, 2, 1, 0)
            if k > 0
        )
        fix = None
        if k == 0 or (fixes and k % 10 == 0):
            # ground track: north at 15 m/s with 3 m/s of wind from the west (east component)
            fix = _fix(t, 15.0 * t * 1e-9, 3.0 * t * 1e-9, (15.0, 3.0))
        out.append(
            Observation(
                frame=k,
                sim_time_ns=t,
                image_bgr=None,
                imu=imu,
                q_ahrs_body_to_ned_wxyz=q,
                airspeed_m_s=airspeed,
                baro_alt_rel_m=200.0,
                gnss=fix,
            )
        )
    return out


def test_deadreckon_integrates_airspeed_along_the_heading() -> None:
    dr = DeadReckoning()
    dr.reset(_context())
    est = [dr.step(o) for o in _observations(501, 0.0, 15.0, fixes=False)]
    last = est[-1]
    assert last is not None and last.enu_m is not None
    # 10 s north at 15 m/s; the 3 m/s of wind is unknown from one fix: 30 m east of truth
    assert last.enu_m == pytest.approx((0.0, 150.0, 200.0), abs=1e-6)
    assert last.cov_enu_m2 is not None and last.cov_enu_m2[0] > 1.5**2


def test_deadreckon_learns_the_wind_while_fixes_keep_coming() -> None:
    dr = DeadReckoning()
    dr.reset(_context())
    for o in _observations(10 * WIND_MIN_FIXES + 1, 0.0, 15.0, fixes=True):
        dr.step(o)
    assert dr.wind_ne_m_s == pytest.approx((0.0, 3.0), abs=1e-6)


def test_deadreckon_without_airspeed_or_baro_holds_the_fix() -> None:
    dr = DeadReckoning()
    dr.reset(_context())
    obs = [
        replace(o, airspeed_m_s=None, baro_alt_rel_m=None)
        for o in _observations(51, math.pi / 2, 15.0, fixes=False)
    ]
    last = [dr.step(o) for o in obs][-1]
    assert last is not None and last.enu_m is not None
    speed = math.hypot(15.0, 3.0)  # the fix's ground speed, held, along the heading (east)
    assert last.enu_m == pytest.approx((speed, 0.0, 200.0), abs=1e-6)


def test_gnss_gating_first_frame_then_outside_denial_windows() -> None:
    row = {
        "gps_time_ns": "1000",
        "gps_fix_type": "3",
        "gps_lat_deg": "54.6",
        "gps_lon_deg": "25.2",
        "gps_alt_amsl_m": "300.0",
        "gps_vn_m_s": "1",
        "gps_ve_m_s": "2",
        "gps_vd_m_s": "0",
    }
    assert _fix_of(row, 0, 1000, None, ()) is not None
    assert _fix_of(row, 5, 2000, None, ()) is None  # no windows: the first frame only
    windows = ((5000, 9000),)
    assert _fix_of(row, 5, 2000, None, windows) is not None
    assert _fix_of(row, 5, 2000, 1000, windows) is None  # the same fix again
    assert _fix_of({**row, "gps_time_ns": "6000"}, 9, 6000, 1000, windows) is None  # denied
    assert _fix_of({**row, "gps_fix_type": "0"}, 0, 1000, None, ()) is None
    manifest = {"gps_denied": [{"start_ns": 5, "end_ns": None}, {"start_ns": 1, "end_ns": 2}]}
    assert denial_windows(manifest) == ((5, 2**63 - 1), (1, 2))


def test_a_zip_is_refused_in_one_line(tmp_path: Path) -> None:
    z = tmp_path / "a.zip"
    z.write_bytes(b"PK")
    with pytest.raises(DatasetError, match=r"a\.zip: a zip archive is read-only"):
        check_writable(z)
    with pytest.raises(DatasetError, match="no such archive folder"):
        check_writable(tmp_path / "missing")


@pytest.mark.parametrize("rpy", [(0.0, 0.0, 0.0), (5.0, -10.0, 30.0)])
def test_the_bus_camera_info_gives_back_the_camera(rpy: tuple[float, float, float]) -> None:
    cam = CameraModel(width_px=320, height_px=240, hfov_deg=60.0, mount_rpy_deg=rpy)
    info = codec.decode_camera_info(
        codec.encode_camera_info(
            codec.CameraInfo(
                width_px=cam.width_px,
                height_px=cam.height_px,
                hfov_deg=cam.hfov_deg,
                rate_hz=50.0,
                q_cam_to_body_wxyz=_q_cam_to_body(cam),
            )
        )
    )
    back = camera_from_info(info)
    assert back.mount_rpy_deg == pytest.approx(rpy, abs=1e-6)
    assert np.allclose(back.r_cam_to_body(), cam.r_cam_to_body(), atol=1e-9)


def _q_cam_to_body(cam: CameraModel) -> tuple[float, float, float, float]:
    r = cam.r_cam_to_body()
    w = math.sqrt(max(0.0, 1.0 + r[0, 0] + r[1, 1] + r[2, 2])) / 2.0
    return (
        w,
        (r[2, 1] - r[1, 2]) / (4 * w),
        (r[0, 2] - r[2, 0]) / (4 * w),
        (r[1, 0] - r[0, 1]) / (4 * w),
    )
