"""Export round trips: rosbag2 (MCAP) and rosbag1 read back with rosbags; TUM files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag1 import Reader as Reader1
from rosbags.rosbag2 import Reader as Reader2
from rosbags.typesys import Stores, get_typestore

import air_sitl.dataset
from air_sitl.cli import main
from air_sitl.dataset.export import TOPIC_GT_POSE, TOPIC_IMAGE, TOPIC_IMU
from air_sitl.dataset.writer import DatasetWriter

from .synth import fly
from .test_writer import _info

FRAMES = 30


@pytest.fixture(scope="module")
def archive_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("export") / "a"
    writer = DatasetWriter(folder, _info())
    fly(writer, FRAMES)
    writer.finish({"capture_distance_m": 1.0})
    return folder


def _read_back(bag: Path, ros1: bool) -> dict[str, list[tuple[int, object]]]:
    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    out: dict[str, list[tuple[int, object]]] = {}
    reader = Reader1(bag) if ros1 else Reader2(bag)
    with reader:
        for conn, t, raw in reader.messages():
            msg = (
                store.deserialize_ros1(raw, conn.msgtype)
                if ros1
                else store.deserialize_cdr(raw, conn.msgtype)
            )
            out.setdefault(conn.topic, []).append((t, msg))
    return out


@pytest.mark.parametrize("ros1", [False, True], ids=["rosbag2", "rosbag1"])
def test_bag_round_trip_has_the_same_frames_and_poses(
    archive_dir: Path, tmp_path: Path, ros1: bool
) -> None:
    out = tmp_path / ("out.bag" if ros1 else "out_bag2")
    flag = "--rosbag1" if ros1 else "--rosbag2"
    assert main(["export", str(archive_dir), flag, str(out)]) == 0
    topics = _read_back(out, ros1)
    with air_sitl.dataset.open(archive_dir) as archive:
        images = topics[TOPIC_IMAGE]
        poses = topics[TOPIC_GT_POSE]
        assert len(images) == len(poses) == len(archive) == FRAMES
        for k, ((t_img, img), (t_pose, pose)) in enumerate(zip(images, poses, strict=True)):
            assert t_img == t_pose == archive.timestamp_ns(k)
            assert bytes(np.asarray(img.data)) == archive.jpeg(k)  # type: ignore[attr-defined]
            row = archive.rows[k]
            p = pose.pose.position  # type: ignore[attr-defined]
            q = pose.pose.orientation  # type: ignore[attr-defined]
            assert (p.x, p.y, p.z) == row.pose_enu_m
            assert (q.x, q.y, q.z, q.w) == row.orientation_xyzw
            assert img.header.stamp.sec * 10**9 + img.header.stamp.nanosec == t_img  # type: ignore[attr-defined]
        imu_lines = (archive_dir / "imu.csv").read_text().splitlines()[1:]
        assert len(topics[TOPIC_IMU]) == len(imu_lines)
        gyro = topics[TOPIC_IMU][0][1].angular_velocity  # type: ignore[attr-defined]
        first = [float(x) for x in imu_lines[0].split(",")[1:4]]
        assert (gyro.x, gyro.y, gyro.z) == (first[0], -first[1], -first[2])  # FRD -> FLU
    assert {"/camera/camera_info", "/gps", "/map_location"} <= set(topics)


def test_tum_ground_truth_and_refusing_to_overwrite(archive_dir: Path, tmp_path: Path) -> None:
    out = tmp_path / "gt.txt"
    assert main(["export", str(archive_dir), "--tum", str(out)]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == FRAMES
    t, x, y, z, *_q = (float(v) for v in lines[3].split())
    with air_sitl.dataset.open(archive_dir) as archive:
        assert abs(t - archive.timestamp_ns(3) / 1e9) < 1e-9
        assert (x, y, z) == archive.rows[3].pose_enu_m
    assert main(["export", str(archive_dir), "--rosbag1", str(out)]) == 2
    assert main(["export", str(archive_dir), "--tum", str(out), "--estimate", "nope"]) == 2


def test_tum_of_an_estimate_file_and_of_the_svo_columns(archive_dir: Path, tmp_path: Path) -> None:
    import shutil

    from air_sitl.dataset.estimates import fill_svo_columns
    from air_sitl.frames import ned2geodetic

    from .synth import HOME

    folder = tmp_path / "a"
    shutil.copytree(archive_dir, folder)
    (folder / "estimates").mkdir()
    lat, lon, alt = ned2geodetic(20.0, 10.0, -200.0, HOME.lat_deg, HOME.lon_deg, HOME.alt_amsl_m)
    (folder / "estimates" / "geo.csv").write_text(
        f"frame,lat_deg,lon_deg,alt_amsl_m,latency_ms\n2,{lat:.10f},{lon:.10f},{alt:.4f},3.5\n"
    )
    out = tmp_path / "geo.txt"
    assert main(["export", str(folder), "--tum", str(out), "--estimate", "geo"]) == 0
    t, x, y, z, *q = (float(v) for v in out.read_text().split())
    with air_sitl.dataset.open(folder) as archive:
        assert t == pytest.approx(archive.timestamp_ns(2) / 1e9)
    assert (x, y, z) == pytest.approx((10.0, 20.0, 200.0), abs=1e-3)
    assert q == [0.0, 0.0, 0.0, 1.0]
    fill_svo_columns(folder, {k: (float(k), 0.0, 1.0) for k in range(0, FRAMES, 2)})
    out = tmp_path / "svo.txt"
    assert main(["export", str(folder), "--tum", str(out), "--estimate", "svo"]) == 0
    lines = out.read_text().splitlines()
    assert len(lines) == (FRAMES + 1) // 2
    assert lines[1].split()[1:4] == ["2.0000", "0.0000", "1.0000"]
    assert main(["check", str(folder)]) == 0


def test_estimates_in_the_bus_log_layout_are_parsed() -> None:
    from air_sitl.dataset.estimates import parse_estimates

    text = (
        "sim_time_ns,frame,east_m,north_m,up_m,lat_deg,lon_deg,alt_amsl_m,qw,qx,qy,qz,"
        "latency_wall_ms,latency_frames\n"
        "100000000,5,1.5,2.5,200.0,54.1,25.1,320.0,,,,,3.2,0\n"
        "120000000,6,1.6,2.6,200.1,54.1,25.1,320.1,1,0,0,0,3.0,1\n"
        "14000"
    )
    points = parse_estimates(text, "estimates/x.csv", None)
    assert [p.frame for p in points] == [5, 6]
    assert points[0].enu_m == (1.5, 2.5, 200.0) and points[0].q_body_to_ned_wxyz is None
    assert points[1].sim_time_ns == 120000000 and points[1].q_body_to_ned_wxyz == (1, 0, 0, 0)
