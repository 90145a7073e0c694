"""The camera's intrinsics and mounting as others take them: one source for every consumer.

``camera.yaml`` of an archive (the ROS ``camera_info`` YAML layout that
``camera_calibration_parsers`` reads: image_width, camera_matrix with rows/cols/data ...,
plus FOV and mounting), the JSON fields a manifest records, and the camera-to-body quaternion
the bus's ``camera/info`` carries. Everything follows from :class:`CameraModel`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import yaml

from air_sitl.camera.effects import effects_from_settings
from air_sitl.camera.model import CameraModel

DEFAULT_MOUNTING = (
    "optical axis along body +z (down), image x (right) along body +y (right wing), "
    "image y (down the image) along body -x (toward the tail): the nose is at the top"
)


def camera_yaml_dict(camera: CameraModel) -> dict[str, Any]:
    """The camera description as a plain dict in ROS camera_info YAML order, then our FOV,
    mounting, noise and effects."""
    width_px, height_px = camera.width_px, camera.height_px
    fx_px, fy_px, cx_px, cy_px = camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px
    mounting = DEFAULT_MOUNTING
    if any(a != 0.0 for a in camera.mount_rpy_deg):
        mounting = f"{DEFAULT_MOUNTING}; then rotated by roll/pitch/yaw {camera.mount_rpy_deg} deg"
    extra: dict[str, Any] = {
        "mount_rpy_deg": [float(a) for a in camera.mount_rpy_deg],
        "noise_sigma": float(camera.noise_sigma),
        "jpeg_quality": int(camera.jpeg_quality),
    }
    distortion: tuple[float, ...] = (0.0,) * 5
    if camera.effects is not None:
        effects = camera.effects
        distortion = effects.distortion
        extra["exposure_time_s"] = float(effects.exposure_time_s)
        extra["effects"] = effects.settings()
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
        "distortion_coefficients": {
            "rows": 1,
            "cols": 5,
            "data": [float(c) for c in distortion],
        },
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
            "q_camera_to_body_frd_wxyz": [round(float(c), 12) for c in q_cam_to_body_wxyz(camera)],
            "description": mounting,
        },
    }
    content["camera_matrix"]["data"] = [float(x) for x in content["camera_matrix"]["data"]]
    content.update(extra)
    return content


def camera_yaml_text(content: Mapping[str, Any]) -> str:
    """YAML text of :func:`camera_yaml_dict` (keys in the given order, deterministic)."""
    return str(yaml.safe_dump(dict(content), sort_keys=False, default_flow_style=None))


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


def q_cam_to_body_wxyz(camera: CameraModel) -> tuple[float, float, float, float]:
    """The camera's mounting as a scalar-first quaternion, camera frame to body FRD."""
    r = camera.r_cam_to_body()
    return matrix_to_quat([[float(r[i][j]) for j in range(3)] for i in range(3)])


def camera_from_settings(settings: Mapping[str, Any]) -> CameraModel:
    """The CameraModel of :meth:`CameraModel.settings` (a remote render request carries them).

    A malformed mapping raises KeyError, TypeError, ValueError or IndexError.
    """
    rpy = tuple(float(a) for a in settings["mount_rpy_deg"])
    effects = settings.get("effects")
    return CameraModel(
        width_px=int(settings["width_px"]),
        height_px=int(settings["height_px"]),
        hfov_deg=float(settings["hfov_deg"]),
        mount_rpy_deg=(rpy[0], rpy[1], rpy[2]),
        noise_sigma=float(settings["noise_sigma"]),
        jpeg_quality=int(settings["jpeg_quality"]),
        effects=None if effects is None else effects_from_settings(effects),
    )


def camera_fields(camera: CameraModel) -> dict[str, Any]:
    """The model's settings and intrinsics as JSON values (what a manifest records)."""
    return {
        **camera.settings(),
        "fx_px": camera.fx_px,
        "fy_px": camera.fy_px,
        "cx_px": camera.cx_px,
        "cy_px": camera.cy_px,
    }


def camera_yaml_for(camera: CameraModel) -> str:
    """``camera.yaml`` of a camera model (ROS camera_info layout + FOV, mounting, noise)."""
    return camera_yaml_text(camera_yaml_dict(camera))
