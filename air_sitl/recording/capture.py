"""``serve --out ROOT``: each capture window of a served flight recorded as ``ROOT/<n>/``.

A served vehicle flies whatever missions clients upload; every time it starts capturing, a
new AIR archive opens, and it is sealed once the window's last frame arrived.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from air_sitl.autopilot.autopilot import Autopilot
from air_sitl.builder import FlightSetup
from air_sitl.camera.coverage import NodataFrames
from air_sitl.camera.info import camera_yaml_for
from air_sitl.clock import CAMERA_PERIOD_NS
from air_sitl.dataset.writer import ArchiveInfo, DatasetWriter
from air_sitl.errors import AirSitlError
from air_sitl.mission.plan_file import plan_text
from air_sitl.recording.inputs import denial_fields, manifest_inputs
from air_sitl.sinks import FlightResult
from air_sitl.state import CameraFrame, SimSample


def capture_manifest(setup: FlightSetup) -> dict[str, Any]:
    """What every archive of a serve run records about its inputs."""
    assert setup.camera is not None
    return (
        manifest_inputs(setup.options, setup.camera, setup.home)
        | {"map": setup.map.spec or "default", "recorded_by": "air-sitl serve"}
        | denial_fields(setup.options)
    )


@dataclass(slots=True)
class _Window:
    """One capture window being recorded."""

    folder: Path
    writer: DatasetWriter
    first_tick: int
    nodata: NodataFrames
    end_tick: int | None = None  # set when capture stops
    next_frame: int = 0
    distance_m: float = 0.0
    last_ne: tuple[float, float] | None = None
    start_ns: int = 0
    # The sample at which capture stopped: the window's end, whenever its last frame arrives
    # (render threads finish at their own pace; the summary must not depend on it).
    end_sample: SimSample | None = None


class CaptureRecorder:
    """A Sink that opens a new AIR archive ``ROOT/<n>/`` for each capture window.

    Frames keep their flight-wide tick index in the runner; each archive renumbers them from 0.
    A window's archive is sealed once its last frame arrived (frames lag behind the samples).
    A write error abandons that archive with a warning: the vehicle keeps flying, and
    ``on_failure`` (serve: a STATUSTEXT of severity ERROR) tells the ground stations.
    """

    def __init__(self, root: Path, setup: FlightSetup) -> None:
        assert setup.camera is not None, "CaptureRecorder: the setup flies without a camera"
        self.root = root
        self.camera_yaml = camera_yaml_for(setup.camera)
        self.manifest = capture_manifest(setup)
        self.autopilot: Autopilot | None = None
        self.archives: list[Path] = []
        self._ticks = 0
        self._window: _Window | None = None
        self._last_sample: SimSample | None = None
        self._failed = False
        self.on_failure: Callable[[str], None] | None = None  # called with one line

    def _next_folder(self) -> Path:
        used = [int(p.name) for p in self.root.glob("*") if p.name.isdigit()]
        return self.root / str(max(used, default=0) + 1)

    def _open(self, sample: SimSample) -> None:
        mission = self.autopilot.mission if self.autopilot is not None else None
        name = (mission.name if mission is not None else "") or "serve"
        text = plan_text(mission) if mission is not None and mission.items else "{}\n"
        folder = self._next_folder()
        info = ArchiveInfo(
            scenario=name,
            camera_yaml=self.camera_yaml,
            plan_name=f"{name}.plan",
            plan_text=text,
            manifest=self.manifest,
            nav_columns=sample.nav is not None,
            agl_column=sample.state.surface_amsl_m is not None,
        )
        writer = DatasetWriter(folder, info)
        nodata = NodataFrames(self.manifest["map"])
        self._window = _Window(
            folder, writer, self._ticks, nodata, start_ns=sample.state.sim_time_ns
        )
        print(f"air-sitl serve: recording into {folder}", flush=True)

    def on_sample(self, sample: SimSample) -> None:
        """Open, feed and close windows following ``capturing``."""
        self._last_sample = sample
        capturing = sample.autopilot.capturing
        try:
            if not capturing:
                self._failed = False
            if (
                capturing
                and not self._failed
                and (self._window is None or self._window.end_tick is not None)
            ):
                if self._window is not None:
                    self._seal()  # frames of the previous window never came: seal it as is
                self._open(sample)
            w = self._window
            if w is not None and w.end_tick is None:
                if capturing:
                    w.writer.on_sample(sample)
                    n, e = sample.state.pos_ned_m[0], sample.state.pos_ned_m[1]
                    if w.last_ne is not None:
                        w.distance_m += math.hypot(n - w.last_ne[0], e - w.last_ne[1])
                    w.last_ne = (n, e)
                else:
                    w.end_tick = self._ticks
                    w.end_sample = sample
                    if w.next_frame >= w.end_tick - w.first_tick:
                        self._seal()
        except AirSitlError as err:
            self._abandon(err)
        if capturing and sample.state.sim_time_ns % CAMERA_PERIOD_NS == 0:
            self._ticks += 1

    def on_frame(self, frame: CameraFrame) -> None:
        """Renumber the frame within its window and hand it to that window's writer (frames
        outside the windows, of a camera kept on for an aid, are not recorded)."""
        w = self._window
        tick = frame.sample.camera
        index = frame.index if tick is None else tick.capture_index
        if w is None or index is None or index < w.first_tick:
            return
        try:
            w.writer.on_frame(dataclasses.replace(frame, index=index - w.first_tick))
            w.nodata.add(index - w.first_tick, frame.nodata_fraction)
            w.next_frame = index - w.first_tick + 1
            if w.end_tick is not None and w.next_frame >= w.end_tick - w.first_tick:
                self._seal()
        except AirSitlError as err:
            self._abandon(err)

    def _seal(self) -> None:
        w = self._window
        self._window = None
        if w is None:
            return
        last = w.end_sample if w.end_sample is not None else self._last_sample
        t = last.state.sim_time_ns if last is not None else 0
        completed = bool(last.autopilot.mission_completed) if last is not None else False
        w.writer.close(FlightResult(mission_completed=completed, sim_time_ns=t, wall_time_s=0.0))
        summary: dict[str, Any] = {
            "capture_distance_m": round(w.distance_m, 2),
            "capture_frames": w.next_frame,
            "capture_start_s": w.start_ns / 1e9,
            "mission_completed": completed,
            "sim_time_s": t / 1e9,
        }
        if (record := w.nodata.record()) is not None:
            summary["frames_with_nodata"] = record
            print(f"{w.nodata.message()} (in {w.folder})", file=sys.stderr, flush=True)
        w.writer.finish(summary)
        self.archives.append(w.folder)
        print(f"air-sitl serve: recorded {w.next_frame} frames into {w.folder}", flush=True)

    def _abandon(self, err: Exception) -> None:
        w = self._window
        self._window = None
        self._failed = True  # no new archive before this capture window ends
        print(f"air-sitl serve: warning: recording stopped: {err}", file=sys.stderr, flush=True)
        if self.on_failure is not None:
            self.on_failure(f"Recording stopped: {err}")
        if w is not None:
            with contextlib.suppress(Exception):
                w.writer.close(FlightResult(mission_completed=False, sim_time_ns=0, wall_time_s=0))

    def close(self, result: FlightResult) -> None:
        """The flight ended: seal the window in progress with what arrived."""
        try:
            self._seal()
        except AirSitlError as err:
            self._abandon(err)
