"""The truth as an aid over zenoh, for the aid tests: :func:`fly_with_truth_aid` runs ``fly``
with this file as the estimator process (``python truth_aid.py ENDPOINT SHIFT_EAST_M``).

The process listens on ENDPOINT, answers every exposure (the ``truth`` of a camera tick
carries its frame index) on ``estimate/aid`` with the true position shifted east, and notes
each ``camera/image`` frame it receives. The answers depend on nothing else, so two runs get the
same ones. Prints ``ready`` once listening; on SIGINT/SIGTERM prints ``answered N`` and
``images [[frame, sim_time_ns], ...]``.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from air_sitl.bus import codec
from air_sitl.bus.keys import KeySpace
from air_sitl.bus.session import BusConfig, Message, open_bus
from air_sitl.bus.signals import wait_until_signalled


def fly_with_truth_aid(plan: Path, out: Path, *options: str, shift_east_m: float = 0.0) -> str:
    """``fly PLAN --out OUT OPTIONS`` aided by the truth (``--nav-aid aid --wait-for aid``, in
    lockstep); the estimator's output (``answered``, ``images``). Asserts both exit 0. Small
    frames: the truth answers them whatever they show."""
    from short_plans import SMALL_CAMERA

    from tests.bus import helpers
    from tests.bus.helpers import cli, free_endpoint, start, stop, wait_for_line

    endpoint = free_endpoint()
    # The estimator listens first so that it hears every truth sample.
    est = start([sys.executable, __file__, endpoint, str(shift_east_m)])
    try:
        wait_for_line(est, "ready")
        run = subprocess.run(
            cli("fly", str(plan), "--out", str(out), "--quiet", "--zenoh-connect", endpoint,
                "--publish-truth", "--nav-aid", "aid", "--wait-for", "aid", *helpers.WAIT_SAFETY,
                *SMALL_CAMERA, *options),
            capture_output=True, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        est_code, est_out, stderr = stop(est)
    assert run.returncode == 0, run.stderr
    assert est_code == 0, stderr
    return est_out


def main(endpoint: str, shift_east_m: float) -> None:
    """Answer the truth of every exposure until signalled."""
    keys = KeySpace()
    answered: list[int] = []
    images: list[tuple[int, int]] = []
    with open_bus(BusConfig(listen=(endpoint,), connect=())) as bus:
        out = bus.publisher(keys.estimate("aid"), encoding=codec.JSON_ENCODING, block=True)

        def on_truth(message: Message) -> None:
            m = json.loads(message.payload)
            if m.get("frame") is None:
                return
            n, e, d = m["pos_ned_m"]
            answer = {
                "frame": m["frame"],
                "sim_time_ns": m["sim_time_ns"],
                "enu_m": [e + shift_east_m, n, -d],
                "cov_enu_m2": [4, 0, 0, 0, 4, 0, 0, 0, 9],
            }
            out.put(json.dumps(answer).encode())
            answered.append(m["frame"])

        def on_image(message: Message) -> None:
            # Lockstep waits for a frame subscriber: this is one.
            meta = codec.decode_frame_meta(message.attachment)
            images.append((meta.frame, meta.sim_time_ns))

        bus.subscribe(keys.truth, on_truth)
        bus.subscribe(keys.image, on_image)
        print("ready", flush=True)
        wait_until_signalled()
        print(f"answered {len(answered)}", flush=True)
        print("images " + json.dumps(images), flush=True)


if __name__ == "__main__":
    main(sys.argv[1], float(sys.argv[2]))
