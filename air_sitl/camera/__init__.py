"""The downward camera: pinhole model, renderer (homography + pyramid), noise, JPEG, bridge."""

from __future__ import annotations

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state, render_camera_frame

__all__ = ["CameraModel", "Renderer", "pose_state", "render_camera_frame"]
