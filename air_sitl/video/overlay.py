"""``--video-overlay``: simulated time, altitude and GNSS state drawn on the stream's frames.

Off by default: a localizer that reads the stream must see the camera's image only.
"""

from __future__ import annotations

import cv2
import numpy as np
import numpy.typing as npt

from air_sitl.state import GpsFix, SimSample

FIX_STALE_NS = 1_000_000_000  # no fix for this long of simulated time: GNSS lost

_FONT = cv2.FONT_HERSHEY_SIMPLEX


def overlay_text(sample: SimSample, gps: GpsFix | None) -> str:
    """``t 12.3 s  alt 120.4 m AMSL 100.2 m AGL  GNSS 3D fix 12 sats`` (or ``GNSS lost``);
    ``gps`` is the latest fix received (samples between fixes carry none)."""
    s = sample.state
    stale = gps is None or s.sim_time_ns - gps.sim_time_ns > FIX_STALE_NS
    if gps is None or stale or gps.fix_type < 3:
        gnss = "GNSS lost"
    else:
        gnss = f"GNSS 3D fix {gps.satellites} sats"
    return (
        f"t {s.sim_time_ns / 1e9:.1f} s  alt {s.alt_amsl_m:.1f} m AMSL {s.alt_agl_m:.1f} m AGL"
        f"  {gnss}"
    )


def draw_overlay(image: npt.NDArray[np.uint8], sample: SimSample, gps: GpsFix | None) -> None:
    """Write the overlay text in place at the top left, white on a dark band."""
    text = overlay_text(sample, gps)
    scale = max(0.35, image.shape[1] / 1400)
    (w, h), base = cv2.getTextSize(text, _FONT, scale, 1)
    cv2.rectangle(image, (0, 0), (min(image.shape[1], w + 8), h + base + 8), (0, 0, 0), -1)
    cv2.putText(image, text, (4, h + 4), _FONT, scale, (255, 255, 255), 1, cv2.LINE_AA)
