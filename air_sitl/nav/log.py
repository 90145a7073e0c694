"""``trajectory.csv`` of a flight on the onboard filter: the truth columns, then the estimate.

With ``--nav ekf`` every row of ``trajectory.csv`` (50 Hz, the whole flight) ends with the
NAV_COLUMNS (``nav_east_m .. nav_std_h_m``, empty before the filter has a position); with
``--nav truth`` the plain :class:`~air_sitl.flightlog.TrajectoryWriter` writes the file as before.
"""

from __future__ import annotations

from pathlib import Path

from air_sitl.clock import CAMERA_PERIOD_NS, NS_PER_S
from air_sitl.dataset.air_schema import NAV_COLUMNS, nav_fields
from air_sitl.flightlog import TRAJECTORY_COLUMNS, TrajectoryWriter, _row
from air_sitl.state import SimSample


class NavTrajectoryWriter(TrajectoryWriter):
    """TrajectoryWriter whose rows carry the onboard estimate too."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        # The base wrote the truth header: replace it (nothing else written yet).
        self._file.seek(0)
        self._file.truncate()
        self._file.write(",".join(TRAJECTORY_COLUMNS + NAV_COLUMNS) + "\n")

    def on_sample(self, sample: SimSample) -> None:
        t = sample.state.sim_time_ns
        if t % CAMERA_PERIOD_NS:
            return
        self._file.write(f"{_row(sample)[:-1]},{nav_fields(sample.nav)}\n")
        if t - self._last_flush_ns >= NS_PER_S:
            self._file.flush()
            self._last_flush_ns = t
