"""Estimates coming back from external localization processes: logged, and awaited in lockstep.

Subscribes to ``air/<vehicle>/estimate/*``. Each estimate of a capture-window frame is written
(on the zenoh thread: it is I/O, not simulation state) to ``estimates/<name>.csv`` under the
frame's capture index (the archive's frame), with its latency in wall milliseconds and in
frames, counted from the moment its frame was published. Estimates of frames outside the
window (a camera kept on for an aid) are awaited and handed to the listeners, not logged.

Every estimate is checked against the contract (:mod:`air_sitl.bus.estimate_contract`) and
against the flight: its frame must have been exposed, its time must lie between the start and
the latest exposure, and one row is kept per frame: the **first** estimate of a frame (what
lockstep waited for) counts, a later one is a rejected duplicate. At most ``max_names``
estimators are heard (one CSV each). Rejections are counted by reason.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from air_sitl.bus import codec
from air_sitl.bus import estimate_contract as contract
from air_sitl.bus.defaults import DEFAULT_MAX_NAMES
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.publisher import FrameLedger
from air_sitl.bus.session import Bus, Message
from air_sitl.frames import geodetic2ned, ned2geodetic
from air_sitl.state import GeoPoint, Quat, Vec3

ESTIMATES_DIR = "estimates"
ESTIMATE_COLUMNS = (
    "sim_time_ns",
    "frame",
    "east_m",
    "north_m",
    "up_m",
    "lat_deg",
    "lon_deg",
    "alt_amsl_m",
    "qw",
    "qx",
    "qy",
    "qz",
    "latency_wall_ms",
    "latency_frames",
    "fix",  # 1: a map fix accepted at this frame, 0: none, empty: the method does not say
)
ESTIMATE_HEADER = ",".join(ESTIMATE_COLUMNS) + "\n"
KEPT_PAYLOADS = 8  # per estimator, the payloads of its latest frames (to know a repeat)


@dataclass(slots=True)
class _Track:
    """What one estimator sent so far."""

    file: IO[str] | None
    frames: set[int] = field(default_factory=set)
    enu_by_frame: dict[int, Vec3] = field(default_factory=dict)  # by capture index
    times: set[int] = field(default_factory=set)  # sim times answered without a frame
    kept: dict[int, bytes] = field(default_factory=dict)  # the latest frames' kept payloads
    rows: int = 0  # logged (capture-window frames, or frames the ledger does not know)
    received: int = 0


class EstimateLog:
    """Receives, converts and logs estimates of every estimator of one vehicle."""

    def __init__(
        self,
        bus: Bus,
        keys: KeySpace,
        ledger: FrameLedger,
        *,
        out_dir: Path | None,
        home: GeoPoint | None,
        max_names: int = DEFAULT_MAX_NAMES,
    ) -> None:
        self.keys = keys
        self.ledger = ledger
        self.out_dir = out_dir
        self.home = home
        self._cond = threading.Condition()
        self._tracks: dict[str, _Track] = {}
        self._closed = False
        self.max_names = max_names
        self.rejected: dict[str, int] = {}  # by reason (estimate_contract.REASONS)
        self.repeats = 0  # identical answers to a frame offered again (not rejections)
        self.first_error: str | None = None
        self._prefix = keys.estimate("x")[:-1]
        # Called with (name, frame, sim_time_ns, estimate or None when refused) on the zenoh
        # thread, before waiters wake (the onboard filter's aid feed, bus/aid_feed.py).
        self.listeners: list[
            Callable[[str, int | None, int | None, codec.Estimate | None], None]
        ] = []
        bus.subscribe(keys.estimates, self._on_message)

    def _on_message(self, message: Message) -> None:
        name = message.key[len(self._prefix) :]
        received = time.monotonic()
        try:
            est = codec.decode_estimate(message.payload, message.key)
            frame, t, wall, last = self._place(est, message.key)
        except contract.EstimateRejectedError as err:
            with self._cond:
                self._reject(err)
                self._tell(name, None, None, None)
            return
        capture = frame if frame is None else self.ledger.capture_index(frame)
        logged = frame is None or capture is not None
        enu, geo = self._positions(est)
        row = ""
        if logged:
            latency_ms = "" if wall is None else f"{(received - wall) * 1e3:.3f}"
            latency_frames = "" if frame is None or wall is None else str(last - frame)
            q = est.q_body_to_ned_wxyz
            row = estimate_row(t, capture, enu, geo, q, latency_ms, latency_frames, est.fix)
        with self._cond:
            if self._closed:
                return
            track = self._tracks.get(name)
            if track is None:
                if len(self._tracks) >= self.max_names:
                    self._reject(
                        contract.EstimateRejectedError(
                            contract.TOO_MANY_NAMES,
                            f"{message.key}: more than {self.max_names} estimators "
                            "(--max-estimate-names)",
                        )
                    )
                    return
                track = _Track(self._open(name))
                self._tracks[name] = track
            answered = track.frames if frame is not None else track.times
            if frame is not None and track.kept.get(frame) == message.payload:
                self.repeats += 1  # the same answer again (a frame offered twice): no news
                return
            if (frame if frame is not None else t) in answered:
                what = f"frame {frame}" if frame is not None else f"sim_time_ns {t}"
                self._reject(
                    contract.EstimateRejectedError(
                        contract.DUPLICATE,
                        f"{message.key}: {what} answered already (the first estimate counts)",
                    )
                )
                return
            track.received += 1
            if logged:
                if track.file is not None:
                    track.file.write(row)
                track.rows += 1
            if frame is not None:
                track.frames.add(frame)
                track.kept[frame] = message.payload
                if len(track.kept) > KEPT_PAYLOADS:
                    del track.kept[next(iter(track.kept))]
                if capture is not None and all(math.isfinite(c) for c in enu):
                    track.enu_by_frame[capture] = enu
            elif t is not None:
                track.times.add(t)
            self._tell(name, frame, t, est)
            self._cond.notify_all()

    def _place(
        self, est: codec.Estimate, key: str
    ) -> tuple[int | None, int | None, float | None, int]:
        """(frame, sim time, publish wall time, last published index) of an estimate inside
        the flight; EstimateRejectedError (outside_flight) for a frame never exposed or a
        time beyond the latest exposure."""
        frame, t, wall, last = self.ledger.lookup(est.frame, est.sim_time_ns)
        now = self.ledger.now_ns
        if est.frame is not None and not self.ledger.exposed(est.frame):
            msg = f"{key}: frame {est.frame} was never taken (latest frame {last})"
            raise contract.EstimateRejectedError(contract.OUTSIDE_FLIGHT, msg)
        if t is not None and (now is None or t > now):
            msg = f"{key}: sim_time_ns {t} is after the flight's time so far ({now})"
            raise contract.EstimateRejectedError(contract.OUTSIDE_FLIGHT, msg)
        return frame, t, wall, last

    def _reject(self, err: contract.EstimateRejectedError) -> None:
        """Count one rejection (under the lock)."""
        self.rejected[err.reason] = self.rejected.get(err.reason, 0) + 1
        self.first_error = self.first_error or str(err)

    def rejected_total(self) -> int:
        """Estimates not taken, all reasons."""
        with self._cond:
            return sum(self.rejected.values())

    def _tell(
        self, name: str, frame: int | None, t: int | None, est: codec.Estimate | None
    ) -> None:
        """Hand the estimate to the listeners (under the lock); a failing one never stops the
        log (lockstep waits on it)."""
        for listener in self.listeners:
            try:
                listener(name, frame, t, est)
            except Exception as err:
                self.first_error = self.first_error or f"estimate listener: {err!r}"

    def _positions(self, est: codec.Estimate) -> tuple[Vec3, GeoPoint | None]:
        nan = math.nan
        home = self.home
        if est.enu_m is not None:
            enu = est.enu_m
            if home is None:
                return enu, est.geo
            lat, lon, alt = ned2geodetic(
                enu[1], enu[0], -enu[2], home.lat_deg, home.lon_deg, home.alt_amsl_m
            )
            return enu, est.geo or GeoPoint(lat_deg=lat, lon_deg=lon, alt_amsl_m=alt)
        geo = est.geo
        if geo is None or home is None:
            return (nan, nan, nan), geo
        n, e, d = geodetic2ned(
            geo.lat_deg, geo.lon_deg, geo.alt_amsl_m, home.lat_deg, home.lon_deg, home.alt_amsl_m
        )
        return (e, n, -d), geo

    def _open(self, name: str) -> IO[str] | None:
        if self.out_dir is None:
            return None
        folder = self.out_dir / ESTIMATES_DIR
        path = folder / f"{name}.csv"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            # Line-buffered: a row is on disk when its estimate arrived, whatever happens next.
            f = path.open("w", encoding="ascii", newline="", buffering=1)
        except OSError as err:
            self.first_error = self.first_error or f"{path}: cannot write: {err.strerror}"
            return None
        f.write(ESTIMATE_HEADER)
        return f

    def has(self, name: str, frame: int) -> bool:
        """True once an estimate for ``frame`` came from ``name``."""
        with self._cond:
            track = self._tracks.get(name)
            return track is not None and frame in track.frames

    def wait_for(self, name: str, frame: int, timeout_s: float) -> bool:
        """Block until ``name`` answered ``frame`` or ``timeout_s`` of wall time passed."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                track = self._tracks.get(name)
                if track is not None and frame in track.frames:
                    return True
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(left)

    def settle(self, quiet_s: float, max_s: float) -> None:
        """Wait for late estimates: until ``quiet_s`` passes without one (at most ``max_s``)."""
        end = time.monotonic() + max_s
        with self._cond:
            while True:
                before = sum(t.received for t in self._tracks.values())
                left = min(quiet_s, end - time.monotonic())
                if left <= 0:
                    return
                self._cond.wait(left)
                if sum(t.received for t in self._tracks.values()) == before:
                    return

    def names(self) -> list[str]:
        """Estimators heard from, sorted."""
        with self._cond:
            return sorted(self._tracks)

    def answered(self, name: str) -> int:
        """Frames ``name`` answered (an estimate naming the frame, or its exposure time)."""
        with self._cond:
            track = self._tracks.get(name)
            return 0 if track is None else len(track.frames)

    def rows(self, name: str) -> int:
        """Estimates of ``name`` logged (those of the capture window's frames)."""
        with self._cond:
            track = self._tracks.get(name)
            return 0 if track is None else track.rows

    def positions_enu(self, name: str) -> dict[int, Vec3]:
        """Latest ENU position per capture frame from ``name`` (for AIR's SvoX..SvoZ)."""
        with self._cond:
            track = self._tracks.get(name)
            return {} if track is None else dict(track.enu_by_frame)

    def close(self) -> None:
        """Stop logging and close the CSV files (later estimates are ignored)."""
        with self._cond:
            self._closed = True
            for track in self._tracks.values():
                if track.file is not None:
                    track.file.close()
                    track.file = None


def estimate_row(
    sim_time_ns: int | None,
    frame: int | None,
    enu_m: Vec3,
    geo: GeoPoint | None,
    q_body_to_ned_wxyz: Quat | None,
    latency_wall_ms: str = "",
    latency_frames: str = "",
    fix: bool | None = None,
) -> str:
    """One line of ``estimates/<name>.csv`` (:data:`ESTIMATE_COLUMNS`, newline included).

    The one home of the format: the bus recorder writes it, offline localization too
    (:mod:`air_sitl.localize.output`); an unknown time, frame, position or attitude is empty
    (a position NaN), and so is ``fix`` when the estimator does not say.
    """
    return (
        ",".join(
            (
                "" if sim_time_ns is None else str(sim_time_ns),
                "" if frame is None else str(frame),
                *("nan" if math.isnan(c) else f"{c:.4f}" for c in enu_m),
                *(
                    ("", "", "")
                    if geo is None
                    else (f"{geo.lat_deg:.9f}", f"{geo.lon_deg:.9f}", f"{geo.alt_amsl_m:.4f}")
                ),
                *(
                    ("", "", "", "")
                    if q_body_to_ned_wxyz is None
                    else tuple(f"{c:.8f}" for c in q_body_to_ned_wxyz)
                ),
                latency_wall_ms,
                latency_frames,
                "" if fix is None else ("1" if fix else "0"),
            )
        )
        + "\n"
    )
