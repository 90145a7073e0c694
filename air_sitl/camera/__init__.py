"""The downward camera: pinhole model, renderer (homography + pyramid), noise, JPEG, bridge.

The package's names load on first use (PEP 562): importing a light submodule (``defaults``,
``options``) for a command's ``--help`` does not load numpy and OpenCV.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from air_sitl.camera.model import CameraModel
    from air_sitl.camera.render import Renderer, pose_state, render_camera_frame

__all__ = ["CameraModel", "Renderer", "pose_state", "render_camera_frame"]

_HOMES = {
    "CameraModel": "air_sitl.camera.model",
    "Renderer": "air_sitl.camera.render",
    "pose_state": "air_sitl.camera.render",
    "render_camera_frame": "air_sitl.camera.render",
}


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        msg = f"module {__name__!r} has no attribute {name!r}"
        raise AttributeError(msg)
    return getattr(importlib.import_module(home), name)
