"""The NED/FRD -> ENU/FLU conversion, pinned on known cases and checked on random attitudes."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from air_sitl.dataset.air_schema import (
    AIR_COLUMNS,
    AIR_HEADER,
)
from air_sitl.frames import (
    euler2quat,
    ned2enu,
    q_flu_enu_to_frd_ned,
    q_frd_ned_to_flu_enu,
    quat_rotate,
)

S = math.sqrt(0.5)


def _close(a: tuple[float, ...], b: tuple[float, ...], tol: float = 1e-12) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b, strict=True))


def test_header_is_the_20_air_columns_in_order() -> None:
    assert AIR_HEADER == (
        "Filename,Latitude,Longitude,RelativeAltitude,ImuX,ImuY,ImuZ,ImuW,PoseX,PoseY,PoseZ,"
        "OrientationX,OrientationY,OrientationZ,OrientationW,MapX,MapY,SvoX,SvoY,SvoZ\n"
    )
    assert len(AIR_COLUMNS) == 20


def test_position_ned_to_enu() -> None:
    assert ned2enu((1.0, 2.0, -3.0)) == (2.0, 1.0, 3.0)


def test_heading_east_90_deg_yaw_is_identity_in_enu_flu() -> None:
    q = q_frd_ned_to_flu_enu(euler2quat(0.0, 0.0, math.radians(90.0)))
    assert _close(q, (1.0, 0.0, 0.0, 0.0))


def test_heading_north_is_90_deg_yaw_about_up_in_enu() -> None:
    q = q_frd_ned_to_flu_enu(euler2quat(0.0, 0.0, 0.0))
    assert _close(q, (S, 0.0, 0.0, S))


def test_right_bank_heading_east_is_positive_roll_about_enu_x() -> None:
    # Right wing down (FRD roll +30) = left wing (FLU +y) up: +30 deg about +x in FLU/ENU.
    q = q_frd_ned_to_flu_enu(euler2quat(math.radians(30.0), 0.0, math.radians(90.0)))
    assert _close(q, (math.cos(math.radians(15.0)), math.sin(math.radians(15.0)), 0.0, 0.0))


def test_nose_up_heading_east_is_negative_rotation_about_flu_y() -> None:
    q = q_frd_ned_to_flu_enu(euler2quat(0.0, math.radians(10.0), math.radians(90.0)))
    assert _close(q, (math.cos(math.radians(5.0)), 0.0, -math.sin(math.radians(5.0)), 0.0))


angles = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)


@given(angles, st.floats(min_value=-1.5, max_value=1.5), angles)
def test_conversion_rotates_vectors_consistently(roll: float, pitch: float, yaw: float) -> None:
    q_ned = euler2quat(roll, pitch, yaw)
    q_enu = q_frd_ned_to_flu_enu(q_ned)
    for v_flu in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)):
        v_frd = (v_flu[0], -v_flu[1], -v_flu[2])
        expected = ned2enu(quat_rotate(q_ned, v_frd))
        assert _close(quat_rotate(q_enu, v_flu), expected, 1e-9)
    back = q_flu_enu_to_frd_ned(q_enu)
    dot = sum(a * b for a, b in zip(q_ned, back, strict=True))
    sign = 1.0 if dot >= 0 else -1.0
    assert _close(tuple(sign * c for c in back), q_ned, 1e-9)


@given(
    angles,
    st.floats(min_value=-1.5, max_value=1.5),
    angles,
    st.tuples(*[st.floats(min_value=-5000.0, max_value=5000.0)] * 3),
)
def test_metadata_row_reads_back_through_the_reader(
    roll: float, pitch: float, yaw: float, ned: tuple[float, float, float]
) -> None:
    import dataclasses

    from air_sitl.dataset.air_schema import metadata_row
    from air_sitl.dataset.reader import parse_air_row

    from .synth import sample_at

    base = sample_at(2_000_000_000, 10)
    q = euler2quat(roll, pitch, yaw)
    state = dataclasses.replace(base.state, pos_ned_m=ned, q_body_to_ned_wxyz=q)
    sample = dataclasses.replace(base, state=state)
    line = metadata_row("frame_000007.jpg", sample, (123, -4))
    row = parse_air_row(line.rstrip("\n").split(","), "test")
    assert row.filename == "frame_000007.jpg" and row.map_xy_px == (123, -4)
    assert _close(row.pose_enu_m, ned2enu(ned), 1e-4)
    x, y, z, w = row.orientation_xyzw
    assert _close((w, x, y, z), q_frd_ned_to_flu_enu(q), 1e-8)
    assert all(math.isnan(c) for c in row.svo_enu_m)
