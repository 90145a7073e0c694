"""Where the data under a flight runs out: the map's nodata in frames, a DEM's extent and holes.

The renderer measures each frame's share of map nodata or off-map pixels
(``CameraFrame.nodata_fraction``, from the alpha channel of the pixels it sampled);
:class:`NodataFrames` collects the frames of the capture window that have any, as ranges of
archive frame indices. :class:`DemCoverage` checks once per simulated second whether the
aircraft, and in the capture window the corners of the frame's ground, are over the DEM's
data (heights beyond its extent are extended from its edge, holes filled from neighbours).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np

from air_sitl.camera.homography import MIN_DOWN, mul3, quat_rows, tuple9
from air_sitl.camera.model import CameraModel
from air_sitl.clock import NS_PER_S
from air_sitl.frames import ned2geodetic
from air_sitl.sinks import NullSink
from air_sitl.state import CameraFrame, SimSample

__all__ = ["DemCoverage", "DemExtent", "NodataFrames", "describe_ranges"]

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
        if index is not None:
            self.add(index, frame.nodata_fraction)

    def add(self, index: int, fraction: float) -> None:
        """Archive frame ``index`` showed ``fraction`` of nodata (frames come in order)."""
        self.frames += 1
        if fraction <= 0.0:
            return
        self.count += 1
        self.max_fraction = max(self.max_fraction, fraction)
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


@runtime_checkable
class DemExtent(Protocol):
    """A surface model that can tell where its file has no data (a GeoTIFF DEM)."""

    name: str

    def coverage_at(self, lat_deg: float, lon_deg: float) -> str | None:
        """None over data; ``"outside"`` beyond the extent, ``"nodata"`` in a hole."""
        ...


_WHAT = {
    ("aircraft", "outside"): "the aircraft flew beyond the DEM",
    ("aircraft", "nodata"): "the aircraft flew over nodata in the DEM",
    ("ground", "outside"): "frames saw ground beyond the DEM",
    ("ground", "nodata"): "frames saw nodata in the DEM",
}
_FIX = {"outside": "heights there extended from its edge", "nodata": "heights there filled"}


class DemCoverage(NullSink):
    """A sink checking once per simulated second that the flight stays over the DEM's data."""

    def __init__(self, dem: DemExtent, camera: CameraModel) -> None:
        self.dem = dem
        c2b_kinv = camera.r_cam_to_body() @ np.linalg.inv(camera.intrinsics())
        self._c2b_kinv = tuple9(c2b_kinv)
        w1, h1 = camera.width_px - 1.0, camera.height_px - 1.0
        self._corners = ((0.0, 0.0), (w1, 0.0), (0.0, h1), (w1, h1))
        self.seconds = 0  # seconds checked
        self.capture_seconds = 0
        self.found: dict[tuple[str, str], list[Any]] = {}  # -> [seconds, t_s, lat, lon]

    def on_sample(self, sample: SimSample) -> None:
        """Check the aircraft's position (and the frame's corners) at whole seconds."""
        st = sample.state
        if st.sim_time_ns % NS_PER_S:
            return
        self.seconds += 1
        self._note("aircraft", self.dem.coverage_at(st.lat_deg, st.lon_deg), st.sim_time_ns,
                   st.lat_deg, st.lon_deg)  # fmt: skip
        if not sample.autopilot.capturing:
            return
        self.capture_seconds += 1
        height = st.surface_agl_m
        r = mul3(quat_rows(st.q_body_to_ned_wxyz), self._c2b_kinv)
        for u, v in self._corners:
            down = r[6] * u + r[7] * v + r[8]
            if height <= 0 or down <= MIN_DOWN:
                continue
            k = height / down
            north, east = (r[0] * u + r[1] * v + r[2]) * k, (r[3] * u + r[4] * v + r[5]) * k
            lat, lon, _ = ned2geodetic(north, east, 0.0, st.lat_deg, st.lon_deg, 0.0)
            kind = self.dem.coverage_at(lat, lon)
            if kind is not None:
                self._note("ground", kind, st.sim_time_ns, lat, lon)
                break

    def _note(self, who: str, kind: str | None, t_ns: int, lat: float, lon: float) -> None:
        if kind is None:
            return
        got = self.found.setdefault((who, kind), [0, t_ns / NS_PER_S, lat, lon])
        got[0] += 1

    def messages(self) -> list[str]:
        """One warning line per finding: how long, and where it first happened."""
        lines = []
        for (who, kind), (n, t_s, lat, lon) in sorted(self.found.items()):
            total = self.seconds if who == "aircraft" else self.capture_seconds
            span = "s" if who == "aircraft" else "s of capture"
            lines.append(
                f"air-sitl: warning: --dem {self.dem.name}: {_WHAT[who, kind]} for {n} of "
                f"{total} {span} (first at {t_s:.0f} s, {lat:.6f}, {lon:.6f}): {_FIX[kind]}"
            )
        return lines
