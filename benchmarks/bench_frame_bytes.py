"""Bytes of one camera frame (640x480 JPEG, default noise) at each JPEG quality over the
procedural maps: the source of the table in :mod:`air_sitl.dataset.size` (``dataset``'s disk
estimate).

Run: ``python benchmarks/bench_frame_bytes.py [--poses N]``. Renders N poses spread over 3 km
around the AIR home of ``urban`` and ``forest`` at 200 m and 300 m above the ground (AIR's two
altitudes), with the default camera (noise 1.8 grey levels), and prints the mean bytes per
frame at each quality, for each map and altitude and over all of them.
"""

from __future__ import annotations

import argparse
import math
import statistics

import cv2

from air_sitl.camera.model import CameraModel
from air_sitl.camera.render import Renderer, pose_state
from air_sitl.frames import ned2geodetic
from air_sitl.maps.open import open_map
from air_sitl.state import GeoPoint

QUALITIES = (50, 60, 70, 75, 80, 85, 90, 95, 100)
HOME = GeoPoint(lat_deg=54.6872, lon_deg=25.2797, alt_amsl_m=0.0)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--poses", type=int, default=12, help="poses per map and altitude")
    args = parser.parse_args()
    camera = CameraModel()
    sizes: dict[int, list[int]] = {q: [] for q in QUALITIES}
    print(f"{'map':8} {'alt':>5} " + " ".join(f"q{q:>6}" for q in QUALITIES))
    for kind in ("urban", "forest"):
        source = open_map(kind, HOME)
        renderer = Renderer(source, camera, seed=0)
        for alt in (200.0, 300.0):
            row: dict[int, list[int]] = {q: [] for q in QUALITIES}
            for i in range(args.poses):
                angle = 2 * math.pi * i / args.poses
                r = 300.0 + 1200.0 * (i % 3)
                lat, lon, _ = ned2geodetic(
                    r * math.cos(angle), r * math.sin(angle), -alt, HOME.lat_deg, HOME.lon_deg, 0.0
                )
                state = pose_state(lat, lon, alt, alt_agl_m=alt, yaw_rad=angle)
                img = renderer.render(state, noise_index=i)
                for q in QUALITIES:
                    _ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, q])
                    row[q].append(len(buf))
                    sizes[q].append(len(buf))
            print(
                f"{kind:8} {alt:5.0f} "
                + " ".join(f"{statistics.mean(row[q]):7.0f}" for q in QUALITIES)
            )
    print(f"{'all':8} {'':5} " + " ".join(f"{statistics.mean(sizes[q]):7.0f}" for q in QUALITIES))


if __name__ == "__main__":
    main()
