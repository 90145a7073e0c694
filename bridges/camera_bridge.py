#!/usr/bin/env python3
"""Standalone camera bridge: renders camera frames for simulators on the zenoh bus.

The same program as ``air-sitl camera-bridge`` (see :mod:`air_sitl.commands.camera_bridge`):
run it on the host that should do the rendering (one with a GPU, later), next to the map::

    python bridges/camera_bridge.py --map urban --zenoh-connect tcp/SIMULATOR:7447

and fly with ``air-sitl fly PLAN --camera remote``; or give the simulator ``--publish-truth``
and ``--no-camera``, and the bridge publishes ``camera/image`` from the truth poses.
"""

from __future__ import annotations

import sys

from air_sitl.cli import main

if __name__ == "__main__":
    sys.exit(main(["camera-bridge", *sys.argv[1:]]))
