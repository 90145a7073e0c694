"""Frames without relief or camera effects stay byte-identical to those of the renderer
before issue 15 (hashes first recorded from commit 789f854 with this same code; recorded again
when issue 15's section 4 redrew the procedural textures, after checking that the renderer of
that commit with the former textures still gave the first hashes; recorded again when issue 24
made each date a survey, with the renderer unchanged)."""

from __future__ import annotations

import hashlib
import math

import pytest
from vehicle_states import above

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer
from air_sitl.maps.open import open_map
from air_sitl.state import GeoPoint

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)

# (map, altitude m, roll deg) -> SHA-256 prefix of the noised pixels, frame index 3.
RECORDED = {
    ("urban", 200.0, 0.0): "81d8f8aa8bc114ad",
    ("urban", 300.0, 20.0): "231260ad95981435",
    ("urban", 3000.0, 5.0): "839560afd0ea05e4",
    ("forest", 200.0, 0.0): "59c6746d41406c4d",
    ("forest", 300.0, 20.0): "e2c44d1da3441afd",
    ("forest", 3000.0, 5.0): "a53b5cbfd4ff2f68",
}


@pytest.mark.parametrize("kind", ["urban", "forest"])
def test_flat_frames_keep_their_bytes(kind: str) -> None:
    renderer = Renderer(open_map(kind, HOME, seed=0), CameraModel(), seed=0)
    for (k, alt, roll), digest in RECORDED.items():
        if k != kind:
            continue
        state = above(HOME, alt, roll_rad=math.radians(roll), pitch_rad=0.03, yaw_rad=0.4)
        got = hashlib.sha256(renderer.render(state, noise_index=3).tobytes()).hexdigest()
        assert got[:16] == digest, (kind, alt, roll)
