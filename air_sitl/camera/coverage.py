"""Which frames show the map's nodata or ground off the map: summary.json's record, one line.

The renderer measures each frame's share of such pixels (``CameraFrame.nodata_fraction``,
from the alpha channel of the pixels it sampled); :class:`NodataFrames` collects the frames
of the capture window that have any, as ranges of archive frame indices.
"""

from __future__ import annotations

from typing import Any

from air_sitl.sinks import NullSink
from air_sitl.state import CameraFrame

__all__ = ["NodataFrames", "describe_ranges"]

_SHOWN_RANGES = 4  # ranges named in the warning line (summary.json holds all of them)


def describe_ranges(ranges: list[list[int]]) -> str:
    """``frames 120-348 and 900-912``, ``frame 7``, ``frames 1, 5-9, 12 and 3 more ranges``."""
    parts = [str(a) if a == b else f"{a}-{b}" for a, b in ranges[:_SHOWN_RANGES]]
    more = len(ranges) - len(parts)
    word = "frame" if len(ranges) == 1 and ranges[0][0] == ranges[0][1] else "frames"
    if more:
        return f"{word} {', '.join(parts)} and {more} more range{'s' if more > 1 else ''}"
    if len(parts) == 1:
        return f"{word} {parts[0]}"
    return f"{word} {', '.join(parts[:-1])} and {parts[-1]}"


class NodataFrames(NullSink):
    """A sink collecting the capture frames that show nodata or off-map ground.

    Frames outside the capture window (a camera kept on for an aid) are not archived and
    not counted; indices are the archive's (``frame_NNNNNN.jpg``).
    """

    def __init__(self, map_name: str) -> None:
        self.map_name = map_name
        self.frames = 0  # capture frames seen
        self.count = 0
        self.max_fraction = 0.0
        self.ranges: list[list[int]] = []

    def on_frame(self, frame: CameraFrame) -> None:
        """Count the frame if it shows any nodata."""
        tick = frame.sample.camera
        index = frame.index if tick is None else tick.capture_index
        if index is None:
            return
        self.frames += 1
        if frame.nodata_fraction <= 0.0:
            return
        self.count += 1
        self.max_fraction = max(self.max_fraction, frame.nodata_fraction)
        if self.ranges and self.ranges[-1][1] == index - 1:
            self.ranges[-1][1] = index
        else:
            self.ranges.append([index, index])

    def record(self) -> dict[str, Any] | None:
        """summary.json's ``frames_with_nodata``: None when every frame saw only map data."""
        if not self.count:
            return None
        return {
            "count": self.count,
            "ranges": [list(r) for r in self.ranges],
            "max_fraction": round(self.max_fraction, 4),
        }

    def message(self) -> str | None:
        """The warning line (None when there is nothing to say)."""
        if not self.count:
            return None
        return (
            f"air-sitl: warning: map {self.map_name}: {describe_ranges(self.ranges)} "
            f"({self.count} of {self.frames}) show nodata or ground off the map: up to "
            f"{self.max_fraction * 100:.1f} % of the frame"
        )
