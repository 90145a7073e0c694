"""Progress of long commands on stderr: tqdm bars on a terminal, plain lines elsewhere.

On a terminal each task is a tqdm bar (count, rate, ETA) redrawn in place. When the stream is
not a terminal (a pipe, a CI log) an in-place bar is noise; the same text, from tqdm's own
formatter, is written as one line each time another 10 % of the total is done, or after 30 s
without a line, and once at the end. :class:`JobsProgress` is ``dataset``'s bar per scenario
plus an overall one; :func:`print_summary` the screen after a flight. Presentation only: the
work reports counts through callbacks and never imports this module.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from typing import IO, TYPE_CHECKING, Any

from air_sitl.closeable import Closeable

if TYPE_CHECKING:  # tqdm (0.1 s with its metadata look-up) loads when a line or bar shows
    from tqdm import tqdm

LINE_STEP = 0.1  # a plain line each time another tenth of the total is done ...
LINE_EVERY_S = 30.0  # ... or after this long without one
_FIGURES = "{desc}: {n_fmt}/{total_fmt}{unit} ({percentage:.0f} %), {rate_noinv_fmt}, "
_LINE = _FIGURES + "ETA {remaining}{postfix}"
_LINE_END = _FIGURES + "{elapsed}{postfix}"
_LINE_NO_TOTAL = "{desc}: {n_fmt}{unit}, {rate_noinv_fmt}, {elapsed}{postfix}"


class Progress(Closeable):
    """One task's progress: ``update_to(n)`` as the count grows, ``close()`` at the end.

    ``total`` None: a count without an end (rate, no ETA). ``enabled`` False: silent (--quiet).
    ``tty`` None: a bar when ``stream`` is a terminal, else lines. ``clock``: for tests.
    ``initial``: what was done before this run (a resumed task): counted, not in the rate;
    so is what the first count holds when the work was not started (:meth:`start`) before it.
    A count past ``total`` raises the total (a forecast ran short): never "3436/3422".
    """

    def __init__(
        self,
        label: str,
        total: float | None,
        *,
        unit: str = "it",
        stream: IO[str] | None = None,
        enabled: bool = True,
        tty: bool | None = None,
        position: int | None = None,
        unit_scale: bool = False,
        clock: Callable[[], float] = time.monotonic,
        initial: float = 0,
    ) -> None:
        self.label = label
        self.total = total if total is None or total > 0 else None
        self.unit = unit
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.tty = _isatty(self.stream) if tty is None else tty
        self.unit_scale = unit_scale
        self.clock = clock
        self.initial = initial
        self.n: float = initial
        self.postfix = ""
        self.closed = False
        self._started = False
        self._start = self._last_line = clock()
        self._next_step = LINE_STEP
        self.position = position
        self._bar: tqdm[Any] | None = None  # on a terminal, from the first count

    def _start_bar(self) -> None:
        from tqdm import tqdm

        self._bar = tqdm(
            total=self.total,
            initial=self.initial,
            desc=self.label,
            unit=f" {self.unit}",
            unit_scale=self.unit_scale,
            file=self.stream,
            position=self.position,
            leave=True,
            dynamic_ncols=True,
            mininterval=0.2,
            smoothing=0.1,
        )

    @property
    def started(self) -> bool:
        """The first count came (the clock and the bar start then)."""
        return self._started

    def set_total(self, total: float | None) -> None:
        """The total became known (or changed)."""
        self.total = total if total is None or total > 0 else None
        if self._bar is not None:
            self._bar.total = self.total
            self._bar.refresh()

    def update_to(self, n: float, postfix: str = "") -> None:
        """The count is now ``n`` (``postfix``: a short note after the figures)."""
        self.n = n
        self.postfix = postfix
        if self.total is not None and n > self.total:  # an estimate ran short (frames of a
            self.set_total(n)  # flight): tqdm would print '?' and 0 % past its total
        if not self.enabled or self.closed:
            return
        if not self._started:  # the clock starts with the work (a job may wait for a worker):
            # what is counted already then (an air start's skipped items, a resumed part)
            # was done before the clock and is never in the rate.
            self.initial = max(self.initial, n)
            self.start()
        if self._bar is not None:
            self._bar.set_postfix_str(postfix, refresh=False)
            self._bar.update(n - self._bar.n)
            return
        now = self.clock()
        frac = n / self.total if self.total else 0.0
        if frac >= 1.0:
            return  # the end: close() says it
        if frac >= self._next_step - 1e-9 or now - self._last_line >= LINE_EVERY_S:
            self._next_step = (math.floor(frac / LINE_STEP + 1e-9) + 1) * LINE_STEP
            self._line(now)

    def start(self) -> None:
        """The work begins now (the clock of the rate starts; on a terminal the bar shows);
        without it the first count starts it."""
        if self._started or not self.enabled or self.closed:
            return
        self._started = True
        self._start = self._last_line = self.clock()
        if self.tty:
            self._start_bar()

    def advance(self, k: float = 1, postfix: str = "") -> None:
        """``k`` more done."""
        self.update_to(self.n + k, postfix)

    def text(self, now: float | None = None, *, end: bool = False) -> str:
        """The progress as one line of text (what a line reports; tqdm's formatter); ``end``:
        the time it took instead of the ETA."""
        from tqdm import tqdm

        elapsed = (self.clock() if now is None else now) - self._start
        line = _LINE_END if end else _LINE
        return tqdm.format_meter(
            self.n,
            self.total,  # type: ignore[arg-type]  # None is documented: no total, no ETA
            elapsed,
            prefix=self.label,
            unit=f" {self.unit}",
            unit_scale=self.unit_scale,
            bar_format=line if self.total else _LINE_NO_TOTAL,
            postfix=self.postfix or None,
            initial=self.initial,
        )

    def _line(self, now: float, *, end: bool = False) -> None:
        self.stream.write(self.text(now, end=end) + "\n")
        self.stream.flush()
        self._last_line = now

    def note(self, line: str) -> None:
        """A line of its own (a warning, a job's result) that does not break the bars."""
        if not self.enabled:
            return
        if self.tty:
            from tqdm import tqdm

            tqdm.write(line, file=self.stream)  # clears the bars, writes, draws them again
        else:
            self.stream.write(line + "\n")
            self.stream.flush()

    def close(self) -> None:
        """The task ended: the bar's final state, or the last line."""
        if self.closed:
            return
        self.closed = True
        if not self._started:
            return  # nothing was counted: nothing to say (an error before the work began)
        if self.total is not None and self.n > self.total:
            self.set_total(self.n)
        if self._bar is not None:
            self._bar.set_postfix_str(self.postfix, refresh=False)
            self._bar.close()
        elif self.enabled:
            self._line(self.clock(), end=True)


class JobsProgress:
    """Many jobs at once (``dataset``): a bar per job and an overall one, frames and ETA.

    Jobs report ``update(name, frames, note)`` (from worker processes, through the parent)
    and ``done(name, frames, line)``. Without a terminal: each job's lines at its tenths and
    the overall line at its tenths or every 30 s.
    """

    def __init__(
        self,
        names: Sequence[str],
        expected: dict[str, int],
        *,
        unit: str = "frames",
        stream: IO[str] | None = None,
        enabled: bool = True,
        tty: bool | None = None,
        already: dict[str, int] | None = None,
        resumed: dict[str, int] | None = None,
    ) -> None:
        self.stream = sys.stderr if stream is None else stream
        tty = _isatty(self.stream) if tty is None else tty
        # Frames of jobs complete before this run (a resumed dataset), and of unfinished jobs
        # on disk already (``resumed``: flown again without rendering): counted from the
        # start, never in a rate.
        already = already or {}
        self.resumed = {n: k for n, k in (resumed or {}).items() if n not in already}
        self.frames = {n: already.get(n, self.resumed.get(n, 0)) for n in names}
        self.finished = 0
        total = sum(expected.get(n, 0) for n in names)
        # Aligned bars on a terminal; lines start with the name.
        width = max((len(n) for n in [*names, "overall"]), default=7) if tty else 0
        self.overall = Progress(
            f"{'overall':>{width}}",
            total or None,
            unit=unit,
            stream=self.stream,
            enabled=enabled,
            tty=tty,
            position=0,
            initial=sum(self.frames.values()),
        )
        self.jobs = {
            name: Progress(
                f"{name:>{width}}",
                expected.get(name) or None,
                unit=unit,
                stream=self.stream,
                enabled=enabled,
                tty=tty,
                position=i + 1,
                initial=self.resumed.get(name, 0),
            )
            for i, name in enumerate(names)
        }

    def update(self, name: str, frames: int, note: str = "") -> None:
        """Job ``name`` has made ``frames`` so far."""
        resumed = self.resumed.get(name, 0)
        if frames < resumed:  # flying again through what is on disk already
            return
        self.frames[name] = frames
        self.jobs[name].update_to(frames, note)
        self.overall.update_to(sum(self.frames.values()))

    def done(self, name: str, frames: int, line: str) -> None:
        """Job ``name`` ended: its bar closes with ``line`` as its note; without a terminal,
        ``[k/N] name: line`` (k jobs ended of N)."""
        self.frames[name] = frames
        self.finished += 1
        job = self.jobs[name]
        job.n = frames
        job.postfix = line
        if job.tty and job.started:
            job.close()  # the bar stays with the line as its note
        else:
            job.closed = True
            job.note(f"[{self.finished}/{len(self.jobs)}] {name}: {frames} frames, {line}")
        self.overall.update_to(sum(self.frames.values()))

    def close(self) -> None:
        """Every bar ends (jobs that never ran close as they are)."""
        for job in self.jobs.values():
            job.close()
        self.overall.close()


def _isatty(stream: IO[str]) -> bool:
    isatty = getattr(stream, "isatty", None)
    return bool(isatty()) if callable(isatty) else False


def _metres(value: object) -> str:
    """``12.3 m``, or ``n/a`` when nothing was measured (null in summary.json)."""
    return f"{value:.1f} m" if isinstance(value, int | float) else "n/a"


def print_summary(
    summary: dict[str, Any], out: object, stream: IO[str], *, camera: bool = True
) -> None:
    """The one-screen summary after a flight (``camera`` False: no frames were captured)."""
    done = "completed" if summary["mission_completed"] else "NOT completed"
    crashed = summary.get("crashed")
    if crashed:
        done = (
            f"NOT completed: CRASHED at {crashed['sim_time_s']:.1f} s, "
            f"{crashed['lat_deg']:.6f}, {crashed['lon_deg']:.6f}: {crashed['reason']}"
        )
    elif not summary["mission_completed"]:
        done = "NOT completed: the time limit (--max-sim-time) ended the flight"
    elif summary.get("landed"):
        done = "completed, landed"
    lines = [
        f"mission {summary.get('plan', '')}: {done}",
        f"  waypoints        {summary['waypoints_reached']}/{summary['waypoints_total']}",
        f"  capture          {summary['capture_frames']} frames, "
        f"{summary['capture_distance_m']:.0f} m"
        if camera
        else f"  capture          no frames (--no-camera); capture window "
        f"{summary['capture_distance_m']:.0f} m",
        f"  max cross-track  {_metres(summary.get('max_cross_track_m'))}",
        f"  max alt error    {_metres(summary.get('max_alt_error_m'))}",
        f"  time             {summary['sim_time_s']:.0f} s simulated in "
        f"{summary['wall_time_s']:.1f} s wall ({summary['realtime_factor']}x)",
        f"  output           {out}",
    ]
    stream.write("\n".join(lines) + "\n")
