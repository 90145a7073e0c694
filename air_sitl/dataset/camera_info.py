"""``camera.yaml``: intrinsics in the ROS ``camera_info`` YAML layout, plus FOV and mounting.

The layout is the one ``camera_calibration_parsers`` reads (image_width, camera_matrix with
rows/cols/data, ...), so ROS tools load it as is; the extra keys describe the mounting.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

DEFAULT_MOUNTING = (
    "optical axis along body +z (down), image x (right) along body +y (right wing), "
    "image y (down the image) along body -x (toward the tail): the nose is at the top"
)


def camera_yaml_dict(
    *,
    width_px: int,
    height_px: int,
    fx_px: float,
    fy_px: float,
    cx_px: float,
    cy_px: float,
    q_camera_to_body_wxyz: Sequence[float],
    mounting: str = DEFAULT_MOUNTING,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The camera description as a plain dict in ROS camera_info YAML order."""
    hfov = math.degrees(2.0 * math.atan(width_px / (2.0 * fx_px)))
    vfov = math.degrees(2.0 * math.atan(height_px / (2.0 * fy_px)))
    content: dict[str, Any] = {
        "image_width": int(width_px),
        "image_height": int(height_px),
        "camera_name": "air_sitl_down",
        "camera_matrix": {
            "rows": 3,
            "cols": 3,
            "data": [float(fx_px), 0.0, float(cx_px), 0.0, float(fy_px), float(cy_px), 0, 0, 1.0],
        },
        "distortion_model": "plumb_bob",
        "distortion_coefficients": {"rows": 1, "cols": 5, "data": [0.0] * 5},
        "rectification_matrix": {
            "rows": 3,
            "cols": 3,
            "data": [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        },
        "projection_matrix": {
            "rows": 3,
            "cols": 4,
            "data": [
                float(fx_px),
                0.0,
                float(cx_px),
                0.0,
                0.0,
                float(fy_px),
                float(cy_px),
                0.0,
                0.0,
                0.0,
                1.0,
                0.0,
            ],
        },
        "hfov_deg": round(hfov, 6),
        "vfov_deg": round(vfov, 6),
        "rate_hz": 50,
        "mounting": {
            "q_camera_to_body_frd_wxyz": [round(float(c), 12) for c in q_camera_to_body_wxyz],
            "description": mounting,
        },
    }
    content["camera_matrix"]["data"] = [float(x) for x in content["camera_matrix"]["data"]]
    if extra:
        content.update(extra)
    return content


def camera_yaml_text(content: Mapping[str, Any]) -> str:
    """YAML text of :func:`camera_yaml_dict` (keys in the given order, deterministic)."""
    import yaml

    return str(yaml.safe_dump(dict(content), sort_keys=False, default_flow_style=None))


def default_camera_yaml(width_px: int = 640, height_px: int = 480, hfov_deg: float = 57.0) -> str:
    """camera.yaml of AIR's camera (pinhole, principal point at the centre, nose up)."""
    f = (width_px / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
    # Camera (x right, y down, z forward) in body FRD: x->+y_b, y->-x_b, z->+z_b.
    q = matrix_to_quat(((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0)))
    return camera_yaml_text(
        camera_yaml_dict(
            width_px=width_px,
            height_px=height_px,
            fx_px=f,
            fy_px=f,
            cx_px=width_px / 2.0,
            cy_px=height_px / 2.0,
            q_camera_to_body_wxyz=q,
        )
    )


def matrix_to_quat(m: Sequence[Sequence[float]]) -> tuple[float, float, float, float]:
    """Rotation matrix (rows; body = M @ camera) to a scalar-first quaternion."""
    tr = m[0][0] + m[1][1] + m[2][2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        return (0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s)
    if m[0][0] > m[1][1] and m[0][0] > m[2][2]:
        s = math.sqrt(1.0 + m[0][0] - m[1][1] - m[2][2]) * 2
        return ((m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s)
    if m[1][1] > m[2][2]:
        s = math.sqrt(1.0 + m[1][1] - m[0][0] - m[2][2]) * 2
        return ((m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s)
    s = math.sqrt(1.0 + m[2][2] - m[0][0] - m[1][1]) * 2
    return ((m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s)
