"""A sink that writes each camera frame as a plain JPEG file into a folder (``fly``)."""

from __future__ import annotations

from pathlib import Path

from air_sitl.errors import DatasetError
from air_sitl.sinks import FlightResult, NullSink
from air_sitl.state import CameraFrame


class JpegFolderSink(NullSink):
    """Writes ``<folder>/<index:06d>.jpg`` for every frame (the dataset writer does more)."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.count = 0
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            msg = f"{folder}: cannot create the frames folder: {err.strerror}"
            raise DatasetError(msg) from None

    def on_frame(self, frame: CameraFrame) -> None:
        """Write the frame's JPEG bytes as they are."""
        (self.folder / f"{frame.index:06d}.jpg").write_bytes(frame.jpeg)
        self.count += 1

    def close(self, result: FlightResult) -> None:
        """Nothing buffered: every frame is on disk when on_frame returns."""
