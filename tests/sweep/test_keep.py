"""``--keep``: what stays of a run's archive once it is scored."""

from __future__ import annotations

from pathlib import Path

import pytest

from air_sitl.sweep.run import _keep

FILES = ("frame_000000.jpg", "metadata.csv", "frames.csv", "imu.csv", "trajectory.csv",
         "summary.json", "manifest.json", "camera.yaml", "estimates/vo.csv")  # fmt: skip


@pytest.mark.parametrize(
    ("keep", "left"),
    [
        ("all", set(FILES)),
        ("frames", set(FILES) - {"frame_000000.jpg"}),
        ("none", {"summary.json", "estimates/vo.csv"}),
    ],
)
def test_keep(tmp_path: Path, keep: str, left: set[str]) -> None:
    for name in FILES:
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("x")
    _keep(tmp_path, keep)
    assert {str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file()} == left
