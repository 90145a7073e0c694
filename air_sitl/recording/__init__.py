"""Recording flights into AIR archives: ``fly``/``dataset`` (:mod:`.archive`), ``serve``'s
capture windows (:mod:`.capture`), and what every archive records of its inputs (:mod:`.inputs`).
"""

from __future__ import annotations

from air_sitl.recording.archive import (
    RecordingRequest,
    RecordingResult,
    folder_problem,
    record_flight,
    resume_problem,
)
from air_sitl.recording.capture import CaptureRecorder
from air_sitl.recording.inputs import manifest_inputs

__all__ = [
    "CaptureRecorder",
    "RecordingRequest",
    "RecordingResult",
    "folder_problem",
    "manifest_inputs",
    "record_flight",
    "resume_problem",
]
