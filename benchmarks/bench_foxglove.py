"""What the Foxglove live view costs a flight: ``fly --speed 0`` CPU, ``serve --speed 10`` pace.

Run: ``python benchmarks/bench_foxglove.py [--leg-m M] [--pairs N] [--serve-leg-m M]``.

1. ``fly --speed 0`` of one capture flight (air start, a ``--leg-m`` capture leg: tens of
   seconds of CPU), without the view (the floor) and with ``--foxglove 127.0.0.1:0`` while a
   client written from the protocol spec (tests/live_view/ws_client.py) subscribes to every
   topic and decodes everything. ``--pairs`` pairs of runs, interleaved (without/with, then
   with/without: a drift of the machine's load falls on both). Prints each side's CPU seconds
   (user + system of the child) as median, min and max, the ratio of the medians (target:
   1.10 or less) and the view's own CPU, measured inside the child: the simulation thread's
   calls into the view, the worker thread that builds the messages, the SDK server's threads.
2. ``serve --speed 10 --no-video`` flying a preloaded capture mission (a ground station built
   from pymavlink sets the mission mode and arms), without and with the view and its reading
   client: the pace (simulated seconds a wall second, from the ``time_boot_ms`` of the
   ATTITUDE the station receives) climbing out before the capture, and while capturing (the
   camera rendered for the view's images, nothing rendered without it), median and spread, and
   serve's CPU (its camera process's too) a simulated second. Target: with the view within 5 %
   of 10x.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import short_plans  # noqa: E402

from air_sitl.state import GeoPoint  # noqa: E402
from tests.live_view.ws_client import FoxgloveClient  # noqa: E402

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)
VIEW_TAG = "bench-foxglove-view-cpu:"
SERVER_THREAD = "tokio-rt-worker"  # the SDK's server threads (Rust, named by tokio)


def _thread_cpu_s(name: str) -> float:
    """CPU seconds of this process's live threads called ``name`` (from /proc)."""
    total = 0.0
    tick = os.sysconf("SC_CLK_TCK")
    for tid in os.listdir("/proc/self/task"):
        with open(f"/proc/self/task/{tid}/stat") as f:
            text = f.read()
        if text[text.index("(") + 1 : text.rindex(")")] == name:
            fields = text[text.rindex(")") + 2 :].split()
            total += (int(fields[11]) + int(fields[12])) / tick
    return total


def child(argv: list[str]) -> int:
    """``--child ARGS``: the CLI with ARGS, the view's own CPU printed on stderr at exit."""
    from air_sitl.cli import main as cli_main
    from air_sitl.foxglove import live

    cpu = {"simulation": 0.0, "worker": 0.0, "server": 0.0}
    cls = live.FoxgloveLive

    def timed(method: Any) -> Any:
        def call(self: Any, *args: Any) -> Any:
            t0 = time.thread_time()
            try:
                return method(self, *args)
            finally:
                cpu["simulation"] += time.thread_time() - t0

        return call

    for name in ("on_sample", "on_frame", "on_image", "on_estimate", "start"):
        setattr(cls, name, timed(getattr(cls, name)))
    work, close = cls._work, cls.close

    def counted_work(self: Any) -> None:
        try:
            work(self)
        finally:
            cpu["worker"] = time.thread_time()

    def counted_close(self: Any, result: Any = None) -> None:
        if self._closed:
            return
        cpu["server"] = _thread_cpu_s(SERVER_THREAD)  # before the server stops
        close(self, result)
        print(f"{VIEW_TAG}{json.dumps(cpu)}", file=sys.stderr, flush=True)

    cls._work, cls.close = counted_work, counted_close  # type: ignore[method-assign]
    return cli_main(argv)


def _children_cpu_s() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _read_all(port: int, counts: dict[str, int]) -> None:
    """Subscribe to every channel as it is advertised; count messages until the server goes."""
    try:
        client = FoxgloveClient("127.0.0.1", port)
        while True:
            topic, _, _ = client.next_message()
            counts[topic] = counts.get(topic, 0) + 1
    except (ConnectionError, OSError):
        return


def _child_cmd(*args: str) -> list[str]:
    return [sys.executable, str(Path(__file__).resolve()), "--child", *args]


class Watched:
    """A child process whose stderr is read on a thread: the view's port starts a reading
    client; the view's CPU line and every line are kept."""

    def __init__(self, cmd: list[str], stdout: int | None = None) -> None:
        env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
        self.proc = subprocess.Popen(
            cmd, stdout=stdout, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT
        )
        self.counts: dict[str, int] = {}
        self.view_cpu: dict[str, float] = {}
        self.lines: list[str] = []
        self.reader: threading.Thread | None = None
        self._thread = threading.Thread(target=self._stderr, daemon=True)
        self._thread.start()

    def _stderr(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self.lines.append(line)
            m = re.search(r"foxglove: ws://127\.0\.0\.1:(\d+)", line)
            if m and self.reader is None:
                self.reader = threading.Thread(
                    target=_read_all, args=(int(m.group(1)), self.counts)
                )
                self.reader.start()
            if VIEW_TAG in line:
                self.view_cpu = json.loads(line.split(VIEW_TAG, 1)[1])

    def wait(self) -> int:
        code = self.proc.wait()
        self._thread.join(30)
        if self.reader is not None:
            self.reader.join(30)
        return code


def fly(plan: Path, out: Path, view: bool) -> tuple[float, Watched]:
    """One flight: the child's CPU seconds, and what it said and the client read."""
    args = ["fly", str(plan), "--out", str(out), "--air-start", "--quiet", "--speed", "0"]
    if view:
        args += ["--foxglove", "127.0.0.1:0"]
    before = _children_cpu_s()
    run = Watched(_child_cmd(*args))
    if run.wait() not in (0, 1):
        raise SystemExit(f"fly failed: {''.join(run.lines)}")
    return _children_cpu_s() - before, run


def spread(values: list[float], digits: int = 2) -> str:
    m, lo, hi = statistics.median(values), min(values), max(values)
    return f"median {m:6.{digits}f} (min {lo:.{digits}f}, max {hi:.{digits}f})"


def bench_fly(leg_m: float, pairs: int, tmp: Path) -> None:
    plan = short_plans.write_short_plan(tmp / "fly.plan", HOME, leg_m=leg_m)
    cpu: dict[bool, list[float]] = {False: [], True: []}
    own: list[dict[str, float]] = []
    last: Watched | None = None
    for k in range(pairs):
        for view in (False, True) if k % 2 == 0 else (True, False):
            seconds, run = fly(plan, tmp / f"fly{k}{int(view)}", view)
            cpu[view].append(seconds)
            if view:
                own.append(run.view_cpu)
                last = run
    summary = json.loads((tmp / "fly00" / "summary.json").read_text())
    floor, with_view = statistics.median(cpu[False]), statistics.median(cpu[True])
    print(
        f"fly --speed 0, {leg_m:g} m capture leg ({summary['sim_time_s']:g} s simulated, "
        f"{summary['capture_frames']} frames), {pairs} interleaved pairs, CPU s (user + system):"
    )
    print(f"  without --foxglove  {spread(cpu[False])}  (floor)")
    print(f"  with --foxglove     {spread(cpu[True])}  a client reading every topic")
    pair_ratios = " ".join(f"{b / a:.3f}" for a, b in zip(cpu[False], cpu[True], strict=True))
    print(f"  ratio of medians    {with_view / floor:6.3f}  (target <= 1.10); pairs: {pair_ratios}")
    parts = {key: statistics.median(o.get(key, 0.0) for o in own) for key in own[0]}
    total = sum(parts.values())
    detail = ", ".join(f"{key} {value:.2f}" for key, value in parts.items())
    share = 100 * total / floor
    print(f"  the view's own CPU  {total:6.2f} s = {share:.1f} % of the floor ({detail})")
    if last is not None:
        n = sum(last.counts.values())
        print(f"  client read         {n} messages on {len(last.counts)} topics (last run)")
        for line in last.lines:
            if line.startswith("foxglove:") and "ws://" not in line:
                print(f"  {line.strip()}")


def serve_pace(plan: Path, view: str) -> dict[str, float]:
    """``serve --speed 10`` flying ``plan`` (``view``: no, or the view's image rate): the pace
    climbing out and while capturing."""
    from mavlink.gcs import PX4_MISSION, Gcs
    from pymavlink import mavutil

    args = ["serve", "--plan", str(plan), "--mavlink", "udpin:127.0.0.1:0", "--no-video"]
    args += ["--speed", "10"]
    if view != "no":
        args += ["--foxglove", "127.0.0.1:0", "--foxglove-image-hz", view]
    # Not the --child: its accounting would cost the simulation thread time at 2000 steps/s.
    before = _children_cpu_s()
    run = Watched([sys.executable, "-m", "air_sitl", *args], stdout=subprocess.PIPE)
    assert run.proc.stdout is not None
    banner = ""
    while "vehicle ready" not in banner:
        banner = run.proc.stdout.readline()
        assert banner or run.proc.poll() is None, "serve did not start"
    port = int(re.findall(r"\(local [^:]+:(\d+)\)", banner)[0])
    gcs = Gcs(f"udpout:127.0.0.1:{port}")
    marks: dict[str, tuple[float, float]] = {}  # event: (wall s, simulated s)
    try:
        gcs.connect()
        m = mavutil.mavlink
        assert gcs.command(m.MAV_CMD_DO_SET_MODE, *PX4_MISSION) == m.MAV_RESULT_ACCEPTED
        assert gcs.command(m.MAV_CMD_COMPONENT_ARM_DISARM, 1) == m.MAV_RESULT_ACCEPTED
        seen = 0
        while "stop" not in marks:
            msg = gcs.recv(["ATTITUDE"], timeout_s=60)
            assert msg is not None, "the vehicle went silent"
            now = (time.monotonic(), gcs.sim_ms / 1000.0)
            marks.setdefault("armed", now)
            for text in gcs.texts[seen:]:
                if "Capture started" in text:
                    marks["start"] = now
                elif "Capture stopped" in text:
                    marks["stop"] = now
            seen = len(gcs.texts)
    finally:
        simulated_s = gcs.sim_ms / 1000.0
        gcs.close()
        run.proc.terminate()
        run.proc.communicate(timeout=60)
        run.wait()

    def pace(a: str, b: str) -> float:
        return (marks[b][1] - marks[a][1]) / (marks[b][0] - marks[a][0])

    return {
        "climb": pace("armed", "start"),
        "capture": pace("start", "stop"),
        "capture_s": marks["stop"][1] - marks["start"][1],
        # serve's CPU (its camera process's too) a simulated second, start-up included
        "cpu": (_children_cpu_s() - before) / simulated_s,
        "images": run.counts.get("/air/uav0/camera/image", 0),
    }


def bench_serve(leg_m: float, pairs: int, tmp: Path) -> None:
    plan = short_plans.write_short_plan(
        tmp / "serve.plan", HOME, leg_m=leg_m, alt_m=100.0, lead_m=600.0
    )
    views = ("no", "10", "0")  # without; with (images at 10 Hz); with, no images
    runs: dict[str, list[dict[str, float]]] = {v: [] for v in views}
    for k in range(pairs):
        for view in views if k % 2 == 0 else views[::-1]:
            runs[view].append(serve_pace(plan, view))
    capture_s = runs["no"][0]["capture_s"]
    print(
        f"serve --speed 10 --no-video, a capture mission ({leg_m:g} m leg, {capture_s:.0f} s "
        f"simulated capturing), {pairs} interleaved runs of each, pace (simulated s / wall s):"
    )
    names = {
        "no": "without --foxglove",
        "10": "with --foxglove (images 10 Hz)",
        "0": "with --foxglove-image-hz 0",
    }
    for phase, what in (("climb", "climbing out"), ("capture", "capturing")):
        print(f"  {what}:")
        floor = statistics.median(r[phase] for r in runs["no"])
        for view in views:
            paces = [r[phase] for r in runs[view]]
            ratio = statistics.median(paces) / floor
            print(f"    {names[view]:32s} {spread(paces)}x  ratio {ratio:.3f}")
    print("  CPU s (user + system, with the camera's process) per simulated s, start-up included:")
    floor = statistics.median(r["cpu"] for r in runs["no"])
    for view in views:
        cpu = [r["cpu"] for r in runs[view]]
        ratio = statistics.median(cpu) / floor
        print(f"    {names[view]:32s} {spread(cpu, 3)}  ratio {ratio:.3f}")
    images = statistics.median(r["images"] for r in runs["10"])
    print(f"  camera images the client read (images 10 Hz): {images:g} (median of the runs)")
    print("  target: with --foxglove 9.5x or more")


def main() -> None:
    if sys.argv[1:2] == ["--child"]:
        sys.exit(child(sys.argv[2:]))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leg-m", type=float, default=1000.0, help="fly's capture leg")
    parser.add_argument("--pairs", type=int, default=3, help="interleaved pairs of runs")
    parser.add_argument("--serve-leg-m", type=float, default=1500.0, help="serve's capture leg")
    parser.add_argument("--serve-pairs", type=int, default=3)
    parser.add_argument("--only", choices=("fly", "serve"), default=None)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.1f} on {os.cpu_count()} cores at the start")
    with tempfile.TemporaryDirectory() as tmp:
        if args.only in (None, "fly"):
            bench_fly(args.leg_m, args.pairs, Path(tmp))
        if args.only in (None, "serve"):
            bench_serve(args.serve_leg_m, args.serve_pairs, Path(tmp))
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
