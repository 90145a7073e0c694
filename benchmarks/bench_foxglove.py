"""What the Foxglove live view costs a flight: ``fly --speed 0`` CPU, ``serve --speed 10`` pace.

Run: ``python benchmarks/bench_foxglove.py [--leg-m M] [--repeat N] [--serve-s S]``.

1. Flies the same short capture flight (air start, a ``--leg-m`` capture leg) as a child
   process, without the view (the floor) and with ``--foxglove 127.0.0.1:0`` while a client
   written from the protocol spec (tests/live_view/ws_client.py) subscribes to every topic and
   reads everything. Prints the child's CPU seconds (user + system), the best of ``--repeat``
   runs, and the ratio to the floor (target: at most 1.10), and what the view dropped.
2. ``serve --speed 10 --max-sim-time S`` with the camera on, without and with the view and
   its reading client: the pace achieved (simulated seconds per wall second from the ready
   line to the exit; target within 5 % of 10x).
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

import short_plans  # noqa: E402

from air_sitl.state import GeoPoint  # noqa: E402
from tests.live_view.ws_client import FoxgloveClient  # noqa: E402

HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=120.0)


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


def fly(plan: Path, out: Path, foxglove: bool) -> tuple[float, dict[str, int], str]:
    """One flight: its CPU seconds, the messages a client read, stderr's foxglove lines."""
    cmd = [sys.executable, "-m", "air_sitl", "fly", str(plan), "--out", str(out)]
    cmd += ["--air-start", "--quiet", "--speed", "0"]
    if foxglove:
        cmd += ["--foxglove", "127.0.0.1:0"]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    before = _children_cpu_s()
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    counts: dict[str, int] = {}
    lines = []
    reader = None
    assert proc.stderr is not None
    for line in proc.stderr:
        lines.append(line)
        m = re.search(r"foxglove: ws://127\.0\.0\.1:(\d+)", line)
        if m and reader is None:
            reader = threading.Thread(target=_read_all, args=(int(m.group(1)), counts))
            reader.start()
    proc.wait()
    if reader is not None:
        reader.join(30)
    if proc.returncode not in (0, 1):
        raise SystemExit(f"fly failed ({proc.returncode}): {''.join(lines)}")
    return _children_cpu_s() - before, counts, "".join(x for x in lines if "foxglove" in x)


def serve_pace(seconds: float, foxglove: bool, image_hz: float = 10.0) -> float:
    """``serve --speed 10`` for ``seconds`` of simulation: simulated s per wall s."""
    cmd = [sys.executable, "-m", "air_sitl", "serve", "--mavlink", "udpin:127.0.0.1:0"]
    cmd += ["--no-video", "--speed", "10", "--max-sim-time", f"{seconds:g}"]
    if foxglove:
        cmd += ["--foxglove", "127.0.0.1:0", "--foxglove-image-hz", f"{image_hz:g}"]
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=ROOT
    )
    counts: dict[str, int] = {}
    assert proc.stderr is not None and proc.stdout is not None
    reader = None
    if foxglove:
        line = proc.stderr.readline()
        m = re.search(r"foxglove: ws://127\.0\.0\.1:(\d+)", line)
        assert m, line
        reader = threading.Thread(target=_read_all, args=(int(m.group(1)), counts))
        reader.start()
    while "vehicle ready" not in proc.stdout.readline():
        assert proc.poll() is None, "serve did not start"
    start = time.monotonic()  # the simulation runs from here
    proc.communicate()
    wall = time.monotonic() - start
    if reader is not None:
        reader.join(30)
    return seconds / wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--leg-m", type=float, default=100.0)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--serve-s", type=float, default=60.0)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        plan = short_plans.write_short_plan(Path(tmp) / "p.plan", HOME, leg_m=args.leg_m)
        best: dict[bool, float] = {}
        read: dict[str, int] = {}
        said = ""
        for k in range(args.repeat):
            for view in (False, True):
                cpu, counts, text = fly(plan, Path(tmp) / f"out{k}{int(view)}", view)
                best[view] = min(best.get(view, cpu), cpu)
                if view:
                    read, said = counts, text
    print(f"fly --speed 0, {args.leg_m:g} m capture leg, best of {args.repeat}:")
    print(f"  without --foxglove   {best[False]:7.2f} s CPU (floor)")
    print(f"  with --foxglove      {best[True]:7.2f} s CPU, a client reading every topic")
    print(f"  ratio                {best[True] / best[False]:7.3f} (target <= 1.10)")
    print(f"  client read          {sum(read.values())} messages on {len(read)} topics")
    for line in said.splitlines():
        print(f"  {line.strip()}")
    paces = {view: serve_pace(args.serve_s, view) for view in (False, True)}
    no_images = serve_pace(args.serve_s, True, image_hz=0.0)
    print(f"serve --speed 10, {args.serve_s:g} s simulated from the ready line to the exit:")
    print(f"  without --foxglove   {paces[False]:6.2f}x (no camera rendered)")
    print(f"  with --foxglove      {paces[True]:6.2f}x, camera on, a client reading every topic")
    print(f"  with, image-hz 0     {no_images:6.2f}x, no camera, a client reading every topic")
    print(f"  with / without       {paces[True] / paces[False]:6.3f} (target: 9.5x or more)")


if __name__ == "__main__":
    main()
